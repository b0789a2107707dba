#include "estimation/render_denoise.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "common/error.h"
#include "common/parallel.h"

namespace lp {

namespace {

/// What pixel (x, y) sees over side x side stratified rays, summed: albedo, shading normal,
/// hit point, the lights' direct radiance (albedo / pi times their irradiance), and the hits;
/// and the sums of the squares of each ray's albedo and direct radiance (channels summed).
struct PixelSums {
  Eigen::Vector3d albedo = Eigen::Vector3d::Zero(), normal = albedo, position = albedo, direct = albedo;
  double albedo_sq = 0, direct_sq = 0;
  int rays = 0, hits = 0;

  /// Whether the rays disagree: some miss the mesh, or the albedo or the direct light of
  /// one differs from their mean by a tenth of it in RMS (a texture's, a shadow's or the
  /// mesh's edge crosses the pixel). Where they do, 16 rays give the pixel's mean roughly.
  bool Varies() const {
    if (hits == 0) return false;
    if (hits < rays) return true;
    const auto spread = [&](double sum, double sq) {
      const double mean = sum / rays;
      return sq / rays - mean * mean > 0.01 * mean * mean;
    };
    return spread(albedo.sum(), albedo_sq) || spread(direct.sum(), direct_sq);
  }
};

PixelSums TracePixel(const RayTracer& scene, const Camera& cam, const std::vector<Light>& lights, int x, int y,
                     int side) {
  PixelSums p;
  p.rays = side * side;
  const std::size_t i = static_cast<std::size_t>(y) * cam.width + x;
  const Eigen::Vector3d origin = cam.center();
  for (int s = 0; s < side * side; ++s) {
    const double u = x - 0.5 + (s % side + 0.5) / side, v = y - 0.5 + (s / side + 0.5) / side;
    SurfacePoint hit;
    if (!scene.Intersect(origin, cam.RayDirection(u, v), &hit)) continue;
    p.albedo += hit.albedo;
    p.albedo_sq += hit.albedo.sum() * hit.albedo.sum();
    if (!lights.empty()) {
      std::int64_t rays = 0;
      const Eigen::Vector3d off = hit.position + hit.geometric * (4 * scene.epsilon());
      const std::uint64_t key = (static_cast<std::uint64_t>(i) << 16) ^ static_cast<std::uint64_t>(s);
      const Eigen::Vector3d direct =
          hit.albedo.cwiseProduct(Irradiance(scene, lights, off, hit.shading, hit.geometric, key, &rays)) / M_PI;
      p.direct += direct;
      p.direct_sq += direct.sum() * direct.sum();
    }
    p.normal += hit.shading;
    p.position += hit.position;
    ++p.hits;
  }
  return p;
}

/// A pixel wholly on one surface: every ray hit, their normals alike.
bool Whole(const PixelGuide& g, std::size_t i) { return g.hit_share[i] >= 1.f && g.normal[i].squaredNorm() > 0.81f; }

/// Pixels on a sharp shadow's edge: the lights' direct irradiance steps by more than a
/// tenth to a neighbour (wholly covered pixels only): an edge may cross the pixel between
/// its 16 rays.
std::vector<std::uint8_t> ShadowEdges(const PixelGuide& g) {
  const std::size_t n = g.direct.size();
  std::vector<float> level(n, 0.f);
  double sum = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float a = g.albedo[i].sum();
    if (!Whole(g, i) || !(a > 1e-3f)) continue;
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
        if (!Whole(g, j)) continue;  // the mesh's edge, not a shadow's
        if (std::abs(level[i] - level[j]) > 0.1f * std::max(level[i], level[j]) + floor) edge[i] = 1;
      }
  }
  return edge;
}

/// Pixel i of `g` from its rays' sums.
void Store(const PixelSums& p, std::size_t i, PixelGuide* g) {
  if (p.hits == 0) return;
  g->albedo[i] = (p.albedo / p.rays).cast<float>();  // the box filter's mean: misses count as black
  g->direct[i] = (p.direct / p.rays).cast<float>();
  g->normal[i] = (p.normal / p.hits).cast<float>();
  g->position[i] = (p.position / p.hits).cast<float>();
  g->hit_share[i] = static_cast<float>(p.hits) / p.rays;
}

}  // namespace

PixelGuide GuideOf(const RayTracer& scene, const Camera& cam, const std::vector<Light>& lights) {
  constexpr int kSide = 4, kFineSide = 12;  // rays a pixel: kSide^2, kFineSide^2 where they disagree
  PixelGuide g;
  g.width = cam.width;
  g.height = cam.height;
  const std::size_t n = static_cast<std::size_t>(cam.width) * cam.height;
  g.albedo.assign(n, Eigen::Vector3f::Zero());
  g.normal.assign(n, Eigen::Vector3f::Zero());
  g.position.assign(n, Eigen::Vector3f::Zero());
  g.direct.assign(n, Eigen::Vector3f::Zero());
  g.hit_share.assign(n, 0.f);
  g.fine.assign(n, 0);
  const auto trace = [&](std::size_t i, int side) {
    return TracePixel(scene, cam, lights, static_cast<int>(i % cam.width), static_cast<int>(i / cam.width), side);
  };
  ParallelForChunks(0, n, 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const PixelSums p = trace(i, kSide);
      Store(p, i, &g);
      g.fine[i] = p.Varies();
    }
  });
  const std::vector<std::uint8_t> edges = ShadowEdges(g);
  std::vector<std::size_t> fine;
  for (std::size_t i = 0; i < n; ++i)
    if (g.fine[i] || edges[i]) fine.push_back(i);
  ParallelForChunks(0, fine.size(), 16, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) {
      Store(trace(fine[k], kFineSide), fine[k], &g);
      g.fine[fine[k]] = 1;
    }
  });
  return g;
}

namespace {

using Features = Eigen::Matrix<double, 5, 1>;  // 1, the pixel offsets, the normal's tilt

/// A neighbour's features in pixel i's fit: 1, its offset, its normal's tilt off i's.
Features FeaturesOf(int dx, int dy, const Eigen::Vector3f& t1, const Eigen::Vector3f& t2, const Eigen::Vector3f& normal) {
  return Features(1, dx, dy, t1.dot(normal), t2.dot(normal));
}

bool InWindow(const std::uint64_t* words, int k) { return (words[k >> 6] >> (k & 63)) & 1u; }

}  // namespace

Denoiser::Denoiser(PixelGuide guide, const Eigen::Vector3d& camera_centre, const DenoiseOptions& o)
    : g_(std::move(guide)), o_(o) {
  LP_CHECK(o.radius >= 0 && o.radius <= 5, "Denoiser: radius " << o.radius << " (at most 5)");
  const std::size_t n = g_.albedo.size();
  const int side = 2 * o.radius + 1;
  for (int k = 0; k < side * side; ++k) {
    const int dx = k % side - o.radius, dy = k / side - o.radius;
    weight_.push_back(static_cast<float>(std::exp(-(dx * dx + dy * dy) / (2 * o.sigma * o.sigma))));
  }
  unit_.resize(n);
  for (std::size_t i = 0; i < n; ++i) unit_[i] = g_.normal[i].normalized();
  const auto usable = [&](std::size_t i) { return Whole(g_, i) && (g_.albedo[i].array() >= 1e-3f).all(); };
  window_.assign(2 * n, 0);
  fit_.assign(n, Fit::Constant(std::nanf("")));
  using Gram = Eigen::Matrix<double, 5, 5>;
  const Features ridge = (Features() << 0, o.pixel_ridge, o.pixel_ridge, o.normal_ridge, o.normal_ridge).finished();
  ParallelForChunks(0, n, 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      if (!usable(i)) continue;
      const int x = static_cast<int>(i % g_.width), y = static_cast<int>(i / g_.width);
      const Eigen::Vector3f& nrm = unit_[i];
      const Eigen::Vector3f t1 = nrm.unitOrthogonal(), t2 = nrm.cross(t1);
      const Eigen::Vector3f& p = g_.position[i];
      const double tolerance = o.max_plane_distance * (p.cast<double>() - camera_centre).norm();
      Gram gram = Gram::Zero();
      for (int k = 0; k < side * side; ++k) {
        const int dx = k % side - o.radius, dy = k / side - o.radius, xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= g_.width || yy >= g_.height) continue;
        const std::size_t j = static_cast<std::size_t>(yy) * g_.width + xx;
        if (!usable(j) || unit_[j].dot(nrm) < o.min_normal_cosine || std::abs(nrm.dot(g_.position[j] - p)) > tolerance)
          continue;
        window_[2 * i + (k >> 6)] |= std::uint64_t{1} << (k & 63);
        gram.selfadjointView<Eigen::Lower>().rankUpdate(FeaturesOf(dx, dy, t1, t2, unit_[j]), weight_[k]);
      }
      gram.diagonal() += gram(0, 0) * ridge;
      const Eigen::LDLT<Gram> ldlt(gram.selfadjointView<Eigen::Lower>());
      const Features row = ldlt.solve(Features::UnitX());  // the fit's value at the pixel: row . moments
      if (ldlt.info() == Eigen::Success && row.allFinite()) fit_[i] = row.cast<float>();
    }
  });
}

ImageRGB Denoiser::operator()(const ImageRGB& image) const {
  LP_CHECK(image.width == g_.width && image.height == g_.height,
           "Denoise: a " << image.width << "x" << image.height << " image, a " << g_.width << "x" << g_.height << " guide");
  const std::size_t n = image.pixels();
  std::vector<Eigen::Vector3f> irradiance(n, Eigen::Vector3f::Zero());  // radiance over albedo where usable
  for (std::size_t i = 0; i < n; ++i)
    if (g_.albedo[i].minCoeff() >= 1e-3f)
      irradiance[i] = Eigen::Map<const Eigen::Vector3f>(image.data.data() + 3 * i).cwiseQuotient(g_.albedo[i]);
  const int side = 2 * o_.radius + 1;
  ImageRGB out = image;
  ParallelForChunks(0, n, 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      float* px = out.data.data() + 3 * i;
      for (int c = 0; c < 3; ++c) px[c] += g_.direct[i][c];
      if (!std::isfinite(fit_[i][0])) continue;
      const int x = static_cast<int>(i % g_.width), y = static_cast<int>(i / g_.width);
      const Eigen::Vector3f& nrm = unit_[i];
      const Eigen::Vector3f t1 = nrm.unitOrthogonal(), t2 = nrm.cross(t1);
      const std::uint64_t* words = &window_[2 * i];
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (int k = 0; k < side * side; ++k) {
        if (!InWindow(words, k)) continue;
        const int dx = k % side - o_.radius, dy = k / side - o_.radius;
        const std::size_t j = static_cast<std::size_t>(y + dy) * g_.width + (x + dx);
        const float kernel = weight_[k] * fit_[i].dot(FeaturesOf(dx, dy, t1, t2, unit_[j]).cast<float>());
        sum += kernel * irradiance[j];
      }
      for (int c = 0; c < 3; ++c) px[c] = g_.albedo[i][c] * sum[c] + g_.direct[i][c];
    }
  });
  return out;
}

ImageRGB Denoise(const ImageRGB& image, const PixelGuide& guide, const Eigen::Vector3d& camera_centre,
                 const DenoiseOptions& options) {
  return Denoiser(guide, camera_centre, options)(image);
}

}  // namespace lp
