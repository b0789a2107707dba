#include "reconstruction/keyframe_vignetting.h"

#include <algorithm>
#include <cmath>

#include "common/parallel.h"
#include "common/rng.h"
#include "scene/ray_tracer.h"

namespace lp {

std::vector<VignettingPair> KeyframeVignettingPairs(const SceneBundle& b, int max_points) {
  const RayTracer tracer(b.mesh);
  // Points spread over the surface by area (a coarse mesh has few vertices, at its edges).
  std::vector<double> cumulative;
  double total = 0;
  for (const Eigen::Vector3i& t : b.mesh.triangles) {
    const Eigen::Vector3f& a = b.mesh.positions[t[0]];
    total += 0.5 * (b.mesh.positions[t[1]] - a).cross(b.mesh.positions[t[2]] - a).norm();
    cumulative.push_back(total);
  }
  const std::size_t samples = cumulative.empty() ? 0 : static_cast<std::size_t>(std::max(1, max_points));
  std::vector<Eigen::Vector3d> points(samples);
  Rng rng(17);
  for (Eigen::Vector3d& p : points) {
    const auto it = std::lower_bound(cumulative.begin(), cumulative.end(), rng.Uniform() * total);
    const Eigen::Vector3i& t = b.mesh.triangles[static_cast<std::size_t>(std::min<std::ptrdiff_t>(
        it - cumulative.begin(), static_cast<std::ptrdiff_t>(cumulative.size()) - 1))];
    double u = rng.Uniform(), v = rng.Uniform();
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const Eigen::Vector3d a = b.mesh.positions[t[0]].cast<double>();
    p = a + u * (b.mesh.positions[t[1]].cast<double>() - a) + v * (b.mesh.positions[t[2]].cast<double>() - a);
  }
  struct Sighting {
    double value, r;
  };
  std::vector<std::vector<Sighting>> seen(samples);
  ParallelFor(0, samples, [&](std::size_t s) {
    const Eigen::Vector3d& p = points[s];
    for (const View& v : b.views) {
      const Camera& c = v.camera;
      double u, w;
      if (!c.Project(p, &u, &w)) continue;
      const int x = static_cast<int>(std::lround(u)), y = static_cast<int>(std::lround(w));
      if (x < 1 || y < 1 || x + 1 >= c.width || y + 1 >= c.height) continue;
      // The mean over 3x3 pixels (less noise), all of them valid (no edge in it).
      double value = 0;
      bool ok = true;
      for (int dy = -1; dy <= 1 && ok; ++dy)
        for (int dx = -1; dx <= 1 && ok; ++dx) {
          const std::size_t q = static_cast<std::size_t>(y + dy) * c.width + x + dx;
          ok = v.valid[q] != 0;
          const float* rgb = v.image.at(x + dx, y + dy);
          value += (rgb[0] + rgb[1] + rgb[2]) / 27.0;
        }
      if (!ok) continue;
      const Eigen::Vector3d to = p - c.center();
      const double dist = to.norm();
      SurfacePoint hit;
      if (!tracer.Intersect(c.center(), to / dist, &hit) || std::abs(hit.distance - dist) > 0.01 + 0.01 * dist)
        continue;  // something else is in front
      if (!(value > 0) || !std::isfinite(value)) continue;
      const double r = std::hypot(u - (0.5 * c.width - 0.5), w - (0.5 * c.height - 0.5)) /
                       (0.5 * std::hypot(static_cast<double>(c.width), static_cast<double>(c.height)));
      seen[s].push_back({value, r});
    }
  });
  std::vector<VignettingPair> pairs;
  for (const auto& list : seen)
    for (std::size_t i = 0; i < list.size(); ++i)
      for (std::size_t j = i + 1; j < list.size(); ++j)
        pairs.push_back({list[i].value, list[i].r, list[j].value, list[j].r});
  return pairs;
}

}  // namespace lp
