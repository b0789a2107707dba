#pragma once
/// The tracers' pixel loop (private to estimation/): which pixels a trace covers, in the
/// transport matrix's row order, and a parallel loop over them in chunks of 64 that polls
/// the cancel callback and sums the path counters.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <vector>

#include "common/error.h"
#include "common/parallel.h"
#include "common/rng.h"
#include "estimation/path_tracer.h"
#include "estimation/sampling.h"
#include "scene/ray_tracer.h"

namespace lp::detail {

struct PixelRef {
  int view;
  int pixel;
};

struct Counters {
  std::int64_t paths = 0, rays = 0, roulette = 0, negligible = 0, max_bounces = 0;
};

/// After a bounce that hit a surface: whether the path goes on, by throughput `T` (paths
/// below options.min_throughput stop as negligible) and, from options.roulette_after on,
/// Russian roulette (survival probability min(0.95, max T), `T` divided by it; one draw).
inline bool PathContinues(int bounce, const TracerOptions& opt, Eigen::Vector3d* T, Rng& rng, Counters& cnt) {
  const double tmax = T->maxCoeff();
  if (tmax < opt.min_throughput) {
    ++cnt.negligible;
    return false;
  }
  if (bounce + 1 >= opt.roulette_after) {
    const double p = std::min(0.95, tmax);
    if (rng.Uniform() >= p) {
      ++cnt.roulette;
      return false;
    }
    *T /= p;
  }
  return true;
}

/// The valid pixels of every view (every pixel when `all_pixels`), view by view, in row order.
inline std::vector<PixelRef> PixelsToTrace(const std::vector<View>& views, bool all_pixels) {
  std::vector<PixelRef> out;
  for (int v = 0; v < static_cast<int>(views.size()); ++v) {
    const int n = views[v].camera.width * views[v].camera.height;
    for (int p = 0; p < n; ++p)
      if (all_pixels || (!views[v].valid.empty() && views[v].valid[p])) out.push_back({v, p});
  }
  return out;
}

/// Runs `per_pixel(index, pixel, counters)` over pixels in parallel.
template <class F>
void ForEachPixel(const std::vector<PixelRef>& pixels, const TracerOptions& opt, TraceStats* stats, F&& per_pixel) {
  std::atomic<std::int64_t> paths{0}, rays{0}, roulette{0}, negligible{0}, max_bounces{0};
  ParallelForChunks(0, pixels.size(), 64, [&](std::size_t b, std::size_t e) {
    if (opt.cancelled && opt.cancelled()) return;
    Counters cnt;
    for (std::size_t i = b; i < e; ++i) per_pixel(i, pixels[i], cnt);
    paths += cnt.paths;
    rays += cnt.rays;
    roulette += cnt.roulette;
    negligible += cnt.negligible;
    max_bounces += cnt.max_bounces;
  });
  if (stats) {
    stats->paths += paths;
    stats->rays += rays;
    stats->stopped_roulette += roulette;
    stats->stopped_negligible += negligible;
    stats->stopped_max_bounces += max_bounces;
  }
}

/// Throws InputError unless a tracer's options trace at least a path of one bounce.
inline void CheckPathOptions(const TracerOptions& o) {
  if (o.spp < 1) throw InputError("spp must be at least 1");
  if (o.bounces < 1) throw InputError("bounces must be at least 1");
}

/// One camera path of pixel (x, y): calls vertex(hit, offset origin, weight) at every
/// surface interaction, weight = throughput x albedo / pi (per sample).
template <class Sink>
void WalkPath(const RayTracer& scene, const Camera& cam, int x, int y, Rng& rng, const TracerOptions& opt,
              Counters& cnt, Sink&& vertex) {
  ++cnt.paths;
  const Eigen::Vector3d origin = cam.center();
  const Eigen::Vector3d dir = cam.RayDirection(x + rng.Uniform() - 0.5, y + rng.Uniform() - 0.5);
  Eigen::Vector3d T(1, 1, 1);
  SurfacePoint hit;
  ++cnt.rays;
  if (!scene.Intersect(origin, dir, &hit)) return;
  const double eps = scene.epsilon();
  for (int bounce = 0;; ++bounce) {
    const Eigen::Vector3d off = hit.position + hit.geometric * (4 * eps);
    vertex(hit, off, Eigen::Vector3d(T.cwiseProduct(hit.albedo) * kInvPi));
    const Eigen::Vector3d w = SampleCosine(hit.shading, rng.Uniform(), rng.Uniform());
    T = T.cwiseProduct(hit.albedo);
    if (hit.geometric.dot(w) <= 0) return;
    if (bounce + 1 >= opt.bounces) {
      ++cnt.max_bounces;
      return;
    }
    ++cnt.rays;
    SurfacePoint next;
    if (!scene.Intersect(off, w, &next)) return;
    if (!PathContinues(bounce, opt, &T, rng, cnt)) return;
    hit = next;
  }
}

}  // namespace lp::detail
