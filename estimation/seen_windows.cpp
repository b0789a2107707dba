#include "estimation/seen_windows.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "estimation/portal.h"
#include "estimation/seen_lamps.h"

namespace lp {

namespace {

struct RimHit {
  Eigen::Vector3d position, normal;  ///< the normal towards the camera
};

/// A blob's pixels within their bounds (x, y from its top left).
struct BlobMask {
  BlobMask(const Camera& c, const ClippedBlob& b)
      : w(b.max_x - b.min_x + 1), h(b.max_y - b.min_y + 1), in(static_cast<std::size_t>(w) * h, 0) {
    for (const int p : b.members) in[(p / c.width - b.min_y) * w + (p % c.width - b.min_x)] = 1;
  }
  bool Inside(int x, int y) const { return x >= 0 && y >= 0 && x < w && y < h; }
  bool Member(int x, int y) const { return Inside(x, y) && in[static_cast<std::size_t>(y) * w + x]; }
  int w, h;
  std::vector<std::uint8_t> in;
};

/// How far (pixels) the blob reaches from its mean pixel along angle `a`: the farthest of
/// its pixels met, in half-pixel steps, within its bounds.
double Reach(const ClippedBlob& b, const BlobMask& m, double a) {
  double reach = 0;
  for (double t = 0;; t += 0.5) {
    const int x = static_cast<int>(std::lround(b.u + t * std::cos(a))) - b.min_x,
              y = static_cast<int>(std::lround(b.v + t * std::sin(a))) - b.min_y;
    if (!m.Inside(x, y)) return reach;
    if (m.Member(x, y)) reach = t;
  }
}

/// The ring of rays around the blob's mean pixel that hit the mesh: on a circle of
/// rim_scale times the blob's radius (`near`: just outside the blob along each ray, at
/// near_scale times its reach there), plus 2 pixels.
std::vector<RimHit> RimHits(const Camera& c, const ClippedBlob& b, const RayTracer& scene, const SeenWindowOptions& o,
                            bool near) {
  const double circle = o.rim_scale * std::sqrt(b.pixels / M_PI) + 2;
  const std::optional<BlobMask> mask = near ? std::optional<BlobMask>(std::in_place, c, b) : std::nullopt;
  std::vector<RimHit> out;
  for (int k = 0; k < o.rim_rays; ++k) {
    const double a = 2 * M_PI * k / o.rim_rays, radius = near ? o.near_scale * Reach(b, *mask, a) + 2 : circle;
    const double u = b.u + radius * std::cos(a), v = b.v + radius * std::sin(a);
    if (u < 0 || v < 0 || u > c.width - 1 || v > c.height - 1) continue;
    const Eigen::Vector3d dir = c.RayDirection(u, v);
    SurfacePoint hit;
    if (!scene.Intersect(c.center(), dir, &hit)) continue;
    out.push_back({hit.position, hit.geometric});  // (facing the ray: towards the camera)
  }
  return out;
}

/// The mean normal and position of `hits`; false when their normals cancel.
bool MeanPlane(const std::vector<RimHit>& hits, Eigen::Vector3d* normal, Eigen::Vector3d* point) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero(), c = Eigen::Vector3d::Zero();
  for (const RimHit& h : hits) n += h.normal, c += h.position;
  if (hits.empty() || n.norm() < 1e-9) return false;
  *normal = n.normalized();
  *point = c / static_cast<double>(hits.size());
  return true;
}

/// The wall the rim lies on: its normal (towards the camera) and a point of it, refitted over
/// the hits on it, when enough of the ring's rays hit one flat surface.
bool RimWall(const std::vector<RimHit>& hits, int rays, const SeenWindowOptions& o, Eigen::Vector3d* normal,
             Eigen::Vector3d* point) {
  Eigen::Vector3d n, c;
  if (hits.size() < o.min_rim_share * rays || !MeanPlane(hits, &n, &c)) return false;
  std::vector<RimHit> flat;
  for (const RimHit& h : hits)
    if (h.normal.dot(n) > o.flat_cos && std::abs((h.position - c).dot(n)) < o.plane_distance) flat.push_back(h);
  if (flat.size() < o.flat_share * hits.size()) return false;
  return MeanPlane(flat, normal, point);  // (without the hits off the wall: a sill, a frame)
}

/// Whether most of the blob's pixels' rays (every n/64-th in the flood fill's order: 64 to
/// 127 of them, or all) leave the scene: a window's do, a bulb's meet the wall behind it, and
/// a window's mullions are few.
bool MostlyEscapes(const Camera& c, const ClippedBlob& b, const RayTracer& scene, const SeenWindowOptions& o) {
  const std::size_t n = b.members.size(), step = std::max<std::size_t>(1, n / 64);
  int tried = 0, escaped = 0;
  for (std::size_t k = step / 2; k < n; k += step) {
    const int p = b.members[k];
    SurfacePoint hit;
    ++tried;
    escaped += !scene.Intersect(c.center(), c.RayDirection(p % c.width, p / c.width), &hit);
  }
  return tried > 0 && escaped >= o.min_escape_share * tried;
}

/// Whether the wall lies at `q` (a point of its plane): a ray along the wall's normal from
/// `distance` before it meets the mesh within `distance` beyond.
bool WallAt(const RayTracer& scene, const Eigen::Vector3d& q, const Eigen::Vector3d& normal, double distance) {
  SurfacePoint hit;
  return scene.Intersect(q + distance * normal, -normal, &hit) && hit.distance < 2 * distance;
}

/// `q` (in the wall's plane, near the hole's edge) moved along the line from the hole's
/// `centre` to the edge, in steps of kEdgeStep and at most kEdgeReach: out to the last point
/// off the wall when it lies in the hole, in to the first off it when on the wall (a blob's
/// pixels at their outer corners reach up to a pixel's footprint onto the wall; its edge
/// pixels, in part wall, may not have clipped); where it meets neither, as it was.
constexpr double kEdgeStep = 0.002, kEdgeReach = 0.1;  // m
Eigen::Vector3d ToTheHolesEdge(const RayTracer& scene, Eigen::Vector3d q, const Eigen::Vector3d& centre,
                               const Eigen::Vector3d& normal, double distance) {
  const Eigen::Vector3d radial = q - centre;
  if (radial.norm() < 1e-9) return q;
  const Eigen::Vector3d step = kEdgeStep * radial.normalized();
  const int steps = static_cast<int>(kEdgeReach / kEdgeStep);
  if (WallAt(scene, q, normal, distance)) {
    for (int k = 1; k <= steps; ++k)
      if (!WallAt(scene, q - k * step, normal, distance)) return q - k * step;
    return q;
  }
  for (int k = 1; k <= steps; ++k)
    if (WallAt(scene, q + k * step, normal, distance)) return q + (k - 1) * step;
  return q;
}

/// Where the rays through the pixel corners on the blob's outer boundary cross the wall's
/// plane, each moved to the hole's edge in the mesh
/// (ToTheHolesEdge); none where one meets it within 6 degrees of edge on (it would stretch
/// the window far).
std::vector<Eigen::Vector3d> OutlineOnWall(const Camera& c, const ClippedBlob& b, const Eigen::Vector3d& normal,
                                           const Eigen::Vector3d& point, const Eigen::Vector3d& centre,
                                           const RayTracer& scene, const SeenWindowOptions& o) {
  const BlobMask mask(c, b);
  const int w = mask.w, h = mask.h;
  const auto member = [&](int x, int y) { return mask.Member(x, y); };
  // The pixel corners on the blob's outer boundary (each once): of the four pixels around
  // corner (x, y), at its top left, some in the blob and some not.
  std::vector<Eigen::Vector3d> out;
  for (int y = 0; y <= h; ++y)
    for (int x = 0; x <= w; ++x) {
      const int around = member(x - 1, y - 1) + member(x, y - 1) + member(x - 1, y) + member(x, y);
      if (around == 0 || around == 4) continue;
      const Eigen::Vector3d d = c.RayDirection(b.min_x + x - 0.5, b.min_y + y - 0.5);
      if (normal.dot(d) > -0.1) return {};
      out.push_back(ToTheHolesEdge(scene, c.center() + (point - c.center()).dot(normal) / normal.dot(d) * d, centre,
                                   normal, o.plane_distance));
    }
  return out;
}

/// Whether `p` lies in `w`'s wall (within `distance` of its plane) and within the rectangle
/// around its outline there.
bool Covers(const SeenWindow& w, const Eigen::Vector3d& p, double distance) {
  if (w.outline.empty() || std::abs((p - w.centre).dot(w.normal)) > distance) return false;
  const Portal r = PortalAround(w.outline, w.centre, w.normal, w.normal.unitOrthogonal());
  const Eigen::Vector3d d = p - r.centre;
  return std::abs(d.dot(r.axis_u)) <= r.half_u && std::abs(d.dot(r.axis_v)) <= r.half_v;
}

/// Whether `x` and `w` are one window: facing alike, and their centres within `merge` or
/// one's centre within the other's outline on its wall (one window seen in parts).
bool OneWindow(const SeenWindow& x, const SeenWindow& w, const SeenWindowOptions& o) {
  return x.normal.dot(w.normal) > o.flat_cos &&
         ((x.centre - w.centre).norm() < o.merge || Covers(x, w.centre, o.plane_distance) ||
          Covers(w, x.centre, o.plane_distance));
}

/// `windows` with each pair that is one window made one (the one seen with more pixels kept),
/// until none is: whatever order the parts and the whole came in.
void MergeParts(std::vector<SeenWindow>* windows, const SeenWindowOptions& o) {
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < windows->size() && !merged; ++i)
      for (std::size_t j = i + 1; j < windows->size() && !merged; ++j)
        if (OneWindow((*windows)[i], (*windows)[j], o)) {
          if ((*windows)[j].pixels > (*windows)[i].pixels) (*windows)[i] = (*windows)[j];
          windows->erase(windows->begin() + static_cast<std::ptrdiff_t>(j));
          merged = true;
        }
  }
}

}  // namespace

std::vector<SeenWindow> SeenWindows(const std::vector<View>& views, const RayTracer& scene, const SeenWindowOptions& o) {
  std::vector<SeenWindow> out;
  for (const ClippedBlob& b : ClippedBlobs(views, o.join)) {
    if (b.pixels < o.min_pixels || 2 * b.off_mesh <= b.pixels) continue;
    const Camera& c = views[b.view].camera;
    const Eigen::Vector3d dir = c.RayDirection(b.u, b.v);
    if (!MostlyEscapes(c, b, scene, o)) continue;  // (a bulb before a wall: the lamps')
    Eigen::Vector3d normal, point;
    // (where the circle finds no one flat wall, the ring just outside the blob: a window
    // large in view beside a room's corner, the circle reaching the side wall)
    if (!RimWall(RimHits(c, b, scene, o, false), o.rim_rays, o, &normal, &point) &&
        !RimWall(RimHits(c, b, scene, o, true), o.rim_rays, o, &normal, &point))
      continue;
    const double along = normal.dot(dir);
    if (along > -1e-3) continue;  // (the wall seen edge on)
    SeenWindow w{b.view, b.pixels, c.center() + (point - c.center()).dot(normal) / along * dir, normal, {}};
    w.outline = OutlineOnWall(c, b, normal, point, w.centre, scene, o);
    out.push_back(w);
    MergeParts(&out, o);
  }
  return out;
}

bool BeyondAWindow(const std::vector<SeenWindow>& windows, const Eigen::Vector3d& p, const Eigen::Vector3d& up,
                   double from) {
  return std::any_of(windows.begin(), windows.end(), [&](const SeenWindow& w) {
    const double depth = (w.centre - p).dot(w.normal), grown = std::max(depth, 0.0);
    Portal hole;
    if (depth < from || !PortalOf(w, up, &hole)) return false;
    const Eigen::Vector3d d = p - hole.centre;
    return std::abs(d.dot(hole.axis_u)) < hole.half_u + grown && std::abs(d.dot(hole.axis_v)) < hole.half_v + grown;
  });
}

}  // namespace lp
