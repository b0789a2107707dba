#include "estimation/seen_windows.h"

#include <algorithm>
#include <cmath>

#include "estimation/portal.h"
#include "estimation/seen_lamps.h"

namespace lp {

namespace {

struct RimHit {
  Eigen::Vector3d position, normal;  ///< the normal towards the camera
};

/// The ring of rays around the blob's mean pixel that hit the mesh.
std::vector<RimHit> RimHits(const Camera& c, const ClippedBlob& b, const RayTracer& scene, const SeenWindowOptions& o) {
  const double radius = o.rim_scale * std::sqrt(b.pixels / M_PI) + 2;
  std::vector<RimHit> out;
  for (int k = 0; k < o.rim_rays; ++k) {
    const double a = 2 * M_PI * k / o.rim_rays, u = b.u + radius * std::cos(a), v = b.v + radius * std::sin(a);
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

}  // namespace

std::vector<SeenWindow> SeenWindows(const std::vector<View>& views, const RayTracer& scene, const SeenWindowOptions& o) {
  std::vector<SeenWindow> out;
  for (const ClippedBlob& b : ClippedBlobs(views, o.join)) {
    if (b.pixels < o.min_pixels || 2 * b.off_mesh <= b.pixels) continue;
    const Camera& c = views[b.view].camera;
    const Eigen::Vector3d dir = c.RayDirection(b.u, b.v);
    if (!MostlyEscapes(c, b, scene, o)) continue;  // (a bulb before a wall: the lamps')
    Eigen::Vector3d normal, point;
    if (!RimWall(RimHits(c, b, scene, o), o.rim_rays, o, &normal, &point)) continue;
    const double along = normal.dot(dir);
    if (along > -1e-3) continue;  // (the wall seen edge on)
    SeenWindow w{b.view, b.pixels, c.center() + (point - c.center()).dot(normal) / along * dir, normal, {}};
    for (const double x : {b.min_x - 0.5, b.max_x + 0.5})
      for (const double y : {b.min_y - 0.5, b.max_y + 0.5}) {
        const Eigen::Vector3d d = c.RayDirection(x, y);
        // (a corner seen within 6 degrees of the wall's plane would stretch it far: none then)
        if (normal.dot(d) < -0.1) w.corners.push_back(c.center() + (point - c.center()).dot(normal) / normal.dot(d) * d);
      }
    auto same = std::find_if(out.begin(), out.end(), [&](const SeenWindow& x) {
      return (x.centre - w.centre).norm() < o.merge && x.normal.dot(w.normal) > o.flat_cos;
    });
    if (same == out.end()) out.push_back(w);
    else if (w.pixels > same->pixels) *same = w;
  }
  return out;
}

bool BeyondAWindow(const std::vector<SeenWindow>& windows, const Eigen::Vector3d& p, const Eigen::Vector3d& up) {
  return std::any_of(windows.begin(), windows.end(), [&](const SeenWindow& w) {
    const double depth = (w.centre - p).dot(w.normal);
    Portal hole;
    if (depth < kBeyondWindow || !PortalOf(w, up, &hole)) return false;
    const Eigen::Vector3d d = p - hole.centre;
    return std::abs(d.dot(hole.axis_u)) < hole.half_u + depth && std::abs(d.dot(hole.axis_v)) < hole.half_v + depth;
  });
}

}  // namespace lp
