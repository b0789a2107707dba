#include "estimation/render_denoise.h"

#include <cmath>

#include "common/error.h"
#include "common/parallel.h"

namespace lp {

PixelGuide GuideOf(const RayTracer& scene, const Camera& cam, const std::vector<Light>& lights) {
  constexpr int kSide = 4;  // kSide^2 stratified rays a pixel
  PixelGuide g;
  g.width = cam.width;
  g.height = cam.height;
  const std::size_t n = static_cast<std::size_t>(cam.width) * cam.height;
  g.albedo.assign(n, Eigen::Vector3f::Zero());
  g.normal.assign(n, Eigen::Vector3f::Zero());
  g.position.assign(n, Eigen::Vector3f::Zero());
  g.direct.assign(n, Eigen::Vector3f::Zero());
  g.hit_share.assign(n, 0.f);
  const Eigen::Vector3d origin = cam.center();
  ParallelForChunks(0, n, 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const int x = static_cast<int>(i % cam.width), y = static_cast<int>(i / cam.width);
      Eigen::Vector3d albedo = Eigen::Vector3d::Zero(), normal = albedo, position = albedo, direct = albedo;
      int hits = 0;
      for (int s = 0; s < kSide * kSide; ++s) {
        const double u = x - 0.5 + (s % kSide + 0.5) / kSide, v = y - 0.5 + (s / kSide + 0.5) / kSide;
        SurfacePoint hit;
        if (!scene.Intersect(origin, cam.RayDirection(u, v), &hit)) continue;
        albedo += hit.albedo;
        if (!lights.empty()) {
          std::int64_t rays = 0;
          const Eigen::Vector3d off = hit.position + hit.geometric * (4 * scene.epsilon());
          const std::uint64_t key = (static_cast<std::uint64_t>(i) << 8) ^ static_cast<std::uint64_t>(s);
          direct += hit.albedo.cwiseProduct(Irradiance(scene, lights, off, hit.shading, hit.geometric, key, &rays)) / M_PI;
        }
        normal += hit.shading;
        position += hit.position;
        ++hits;
      }
      if (hits == 0) continue;
      g.albedo[i] = (albedo / (kSide * kSide)).cast<float>();  // the box filter's mean: misses count as black
      g.direct[i] = (direct / (kSide * kSide)).cast<float>();
      g.normal[i] = (normal / hits).cast<float>();
      g.position[i] = (position / hits).cast<float>();
      g.hit_share[i] = static_cast<float>(hits) / (kSide * kSide);
    }
  });
  return g;
}

namespace {

/// Pixels on a sharp shadow's edge: the lights' direct irradiance steps by more than a
/// tenth to a neighbour. There the guide's 16 rays give the edge's coverage only roughly,
/// an error from one pixel to the next that smoothing would not take out, and keep.
template <class Whole>
std::vector<std::uint8_t> ShadowEdges(const PixelGuide& g, const Whole& whole) {
  const std::size_t n = g.direct.size();
  std::vector<float> level(n, 0.f);
  double sum = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float a = g.albedo[i].sum();
    if (!whole(i) || !(a > 1e-3f)) continue;
    level[i] = g.direct[i].sum() / a;
    sum += level[i];
    ++count;
  }
  std::vector<std::uint8_t> edge(n, 0);
  if (!(sum > 0)) return edge;
  const float floor = static_cast<float>(0.02 * sum / count);
  for (std::size_t i = 0; i < n; ++i) {
    const int x = static_cast<int>(i % g.width), y = static_cast<int>(i / g.width);
    for (int dy = -1; dy <= 1 && !edge[i]; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= g.width || yy >= g.height) continue;
        const std::size_t j = static_cast<std::size_t>(yy) * g.width + xx;
        if (!whole(j)) continue;  // the mesh's edge, not a shadow's
        if (std::abs(level[i] - level[j]) > 0.1f * std::max(level[i], level[j]) + floor) edge[i] = 1;
      }
  }
  return edge;
}

}  // namespace

ImageRGB Denoise(const ImageRGB& image, const PixelGuide& g, const Eigen::Vector3d& camera_centre,
                 const DenoiseOptions& o) {
  LP_CHECK(image.width == g.width && image.height == g.height,
           "Denoise: a " << image.width << "x" << image.height << " image, a " << g.width << "x" << g.height << " guide");
  const std::size_t n = image.pixels();
  const auto whole = [&](std::size_t i) { return g.hit_share[i] >= 1.f && g.normal[i].squaredNorm() > 0.81f; };
  // Each wholly covered pixel's irradiance per channel (NaN where its albedo is too dark).
  std::vector<Eigen::Vector3f> irradiance(n, Eigen::Vector3f::Constant(std::nanf("")));
  for (std::size_t i = 0; i < n; ++i)
    if (whole(i))
      for (int c = 0; c < 3; ++c)
        if (g.albedo[i][c] >= 1e-3f) irradiance[i][c] = (image.data[3 * i + c] - g.direct[i][c]) / g.albedo[i][c];
  const std::vector<std::uint8_t> edge = ShadowEdges(g, whole);
  std::vector<Eigen::Vector3f> unit(n);  // the normals, each normalized once
  for (std::size_t i = 0; i < n; ++i) unit[i] = g.normal[i].normalized();
  ImageRGB out = image;
  const double inv = 1 / (2 * o.sigma * o.sigma);
  ParallelForChunks(0, n, 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      if (!whole(i) || edge[i]) continue;
      const int x = static_cast<int>(i % g.width), y = static_cast<int>(i / g.width);
      const Eigen::Vector3f& nrm = unit[i];
      const Eigen::Vector3f& p = g.position[i];
      const double tolerance = o.max_plane_distance * (p.cast<double>() - camera_centre).norm();
      Eigen::Vector3d sum = Eigen::Vector3d::Zero(), weight = sum;
      for (int dy = -o.radius; dy <= o.radius; ++dy)
        for (int dx = -o.radius; dx <= o.radius; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= g.width || yy >= g.height) continue;
          const std::size_t j = static_cast<std::size_t>(yy) * g.width + xx;
          if (!whole(j) || edge[j] || unit[j].dot(nrm) < o.min_normal_cosine ||
              std::abs(nrm.dot(g.position[j] - p)) > tolerance)
            continue;
          const double w = std::exp(-(dx * dx + dy * dy) * inv);
          for (int c = 0; c < 3; ++c)
            if (std::isfinite(irradiance[j][c])) {
              sum[c] += w * irradiance[j][c];
              weight[c] += w;
            }
        }
      for (int c = 0; c < 3; ++c)
        if (std::isfinite(irradiance[i][c]) && weight[c] > 0)
          out.data[3 * i + c] = static_cast<float>(g.albedo[i][c] * sum[c] / weight[c] + g.direct[i][c]);
    }
  });
  return out;
}

}  // namespace lp
