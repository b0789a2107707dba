#include "estimation/seen_lamps.h"

#include <algorithm>
#include <cmath>

#include "estimation/sampling.h"

namespace lp {

namespace {

bool Flagged(const std::vector<std::uint8_t>& flags, std::size_t p) { return p < flags.size() && flags[p]; }

/// The blobs of one view: clipped pixels within `join` of each other, by a flood fill.
void ViewBlobs(const View& view, int index, int join, std::vector<ClippedBlob>* out) {
  const int w = view.camera.width, h = view.camera.height;
  if (view.clipped.empty() && view.clipped_off.empty()) return;
  const auto clipped = [&](std::size_t p) { return Flagged(view.clipped, p) || Flagged(view.clipped_off, p); };
  std::vector<std::uint8_t> seen(static_cast<std::size_t>(w) * h, 0);
  std::vector<std::size_t> stack;
  for (std::size_t start = 0; start < seen.size(); ++start) {
    if (seen[start] || !clipped(start)) continue;
    ClippedBlob blob;
    blob.view = index;
    double su = 0, sv = 0;
    blob.min_x = blob.max_x = static_cast<int>(start % w);
    blob.min_y = blob.max_y = static_cast<int>(start / w);
    seen[start] = 1;
    stack.assign(1, start);
    while (!stack.empty()) {
      const std::size_t p = stack.back();
      stack.pop_back();
      const int x = static_cast<int>(p % w), y = static_cast<int>(p / w);
      ++blob.pixels;
      blob.members.push_back(static_cast<int>(p));
      blob.off_mesh += Flagged(view.clipped_off, p);
      su += x;
      sv += y;
      blob.min_x = std::min(blob.min_x, x), blob.max_x = std::max(blob.max_x, x);
      blob.min_y = std::min(blob.min_y, y), blob.max_y = std::max(blob.max_y, y);
      for (int dy = -join; dy <= join; ++dy)
        for (int dx = -join; dx <= join; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
          const std::size_t q = static_cast<std::size_t>(ny) * w + nx;
          if (seen[q] || !clipped(q)) continue;
          seen[q] = 1;
          stack.push_back(q);
        }
    }
    blob.u = su / blob.pixels;
    blob.v = sv / blob.pixels;
    out->push_back(blob);
  }
}

struct Ray {
  Eigen::Vector3d origin, dir;
  double pixel = 0;  ///< a pixel's angle (radians) there: 1 / the focal length
};

Ray BlobRay(const std::vector<View>& views, const ClippedBlob& b) {
  const Camera& c = views[b.view].camera;
  return {c.center(), c.RayDirection(b.u, b.v), 1 / std::max(c.fx, 1e-9)};
}

/// The covariance of the least-squares meeting point of rays a and b, reached `s` and `t`
/// along them, each ray's direction kSeenPixelSigma pixels off: the inverse of the sum of
/// their information, (I - d d^T) / sigma^2 with sigma the pixel's width there.
Eigen::Matrix3d MeetingCovariance(const Ray& a, double s, const Ray& b, double t) {
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (const auto& [ray, along] : {std::pair<const Ray&, double>{a, s}, {b, t}}) {
    const double sigma = std::max(kSeenPixelSigma * ray.pixel * along, 1e-6);
    information += (Eigen::Matrix3d::Identity() - ray.dir * ray.dir.transpose()) / (sigma * sigma);
  }
  return information.inverse();
}

/// Where two blobs' rays (from different views) meet: false when they are too near
/// parallel, meet behind a camera, miss each other, or meet behind the surface a ray hits.
bool Triangulate(const Ray& a, const Ray& b, const RayTracer& scene, const SeenLampOptions& o, SeenLamp* out) {
  const double cos_ab = a.dir.dot(b.dir);
  if (cos_ab > std::cos(o.min_angle_deg * kPi / 180)) return false;
  // Closest points a.origin + s a.dir and b.origin + t b.dir.
  const Eigen::Vector3d w0 = a.origin - b.origin;
  const double d = a.dir.dot(w0), e = b.dir.dot(w0), den = 1 - cos_ab * cos_ab;
  const double s = (cos_ab * e - d) / den, t = (e - cos_ab * d) / den;
  if (s < 0.1 || t < 0.1) return false;
  const Eigen::Vector3d pa = a.origin + s * a.dir, pb = b.origin + t * b.dir, mid = 0.5 * (pa + pb);
  const double gap = (pa - pb).norm(), distance = 0.5 * (s + t);
  const double tolerance = o.gap_base + o.gap_per_metre * distance;
  if (gap > tolerance) return false;
  // Seen in front of what each ray hits (a bulb before a wall), not behind it.
  for (const auto& [ray, along] : {std::pair<const Ray&, double>{a, s}, {b, t}}) {
    SurfacePoint hit;
    if (scene.Intersect(ray.origin, ray.dir, &hit) && hit.distance < along - tolerance) return false;
  }
  out->position = mid;
  out->how = "triangulated";
  out->gap = 0.5 * gap;
  out->covariance = MeetingCovariance(a, s, b, t) + out->gap * out->gap * Eigen::Matrix3d::Identity();
  return true;
}

/// Places closer than options.merge are one (their pixels' weighted mean, their views'
/// count the most of either), the most pixels first.
std::vector<SeenLamp> Merged(std::vector<SeenLamp> lamps, const SeenLampOptions& o) {
  std::stable_sort(lamps.begin(), lamps.end(), [](const SeenLamp& x, const SeenLamp& y) { return x.pixels > y.pixels; });
  std::vector<SeenLamp> out;
  for (const SeenLamp& l : lamps) {
    auto near = std::find_if(out.begin(), out.end(),
                             [&](const SeenLamp& m) { return (m.position - l.position).norm() < o.merge; });
    if (near == out.end()) {
      out.push_back(l);
      continue;
    }
    const double wn = near->pixels, wl = l.pixels;
    near->position = (wn * near->position + wl * l.position) / (wn + wl);
    near->pixels += l.pixels;
    near->views = std::max(near->views, l.views);
    near->gap = std::max(near->gap, l.gap);
    if (l.covariance.trace() > near->covariance.trace()) near->covariance = l.covariance;  // (the less sure)
  }
  std::stable_sort(out.begin(), out.end(), [](const SeenLamp& x, const SeenLamp& y) { return x.pixels > y.pixels; });
  if (static_cast<int>(out.size()) > o.max_lamps) out.resize(o.max_lamps);
  return out;
}

}  // namespace

std::vector<ClippedBlob> ClippedBlobs(const std::vector<View>& views, int join) {
  std::vector<ClippedBlob> out;
  for (std::size_t k = 0; k < views.size(); ++k) ViewBlobs(views[k], static_cast<int>(k), std::max(1, join), &out);
  return out;
}

std::vector<SeenLamp> SeenLamps(const std::vector<View>& views, const RayTracer& scene, const SeenLampOptions& o) {
  std::vector<ClippedBlob> off;
  std::vector<SeenLamp> lamps;
  for (const ClippedBlob& b : ClippedBlobs(views)) {
    const double share = static_cast<double>(b.pixels) / (views[b.view].camera.width * views[b.view].camera.height);
    if (b.pixels < o.min_pixels || share > o.max_view_share) continue;
    if (2 * b.off_mesh > b.pixels) {
      off.push_back(b);
      continue;
    }
    const Ray r = BlobRay(views, b);
    SurfacePoint hit;
    if (!scene.Intersect(r.origin, r.dir, &hit)) continue;
    SeenLamp l;
    l.position = hit.position - std::min(o.towards_camera, 0.5 * hit.distance) * r.dir;
    l.how = "depth";
    l.views = 1;
    l.pixels = b.pixels;
    lamps.push_back(l);
  }
  for (std::size_t i = 0; i < off.size(); ++i)
    for (std::size_t j = i + 1; j < off.size(); ++j) {
      if (off[i].view == off[j].view) continue;
      SeenLamp l;
      if (!Triangulate(BlobRay(views, off[i]), BlobRay(views, off[j]), scene, o, &l)) continue;
      l.views = 2;
      l.pixels = off[i].pixels + off[j].pixels;
      lamps.push_back(l);
    }
  return Merged(std::move(lamps), o);
}

}  // namespace lp
