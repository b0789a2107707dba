#pragma once
/// Monte Carlo estimation of the light-transport matrix A for an environment map
/// of discrete cells, and the relighting render with the same paths.
#include <cstdint>
#include <functional>
#include <vector>

#include "common/image.h"
#include "common/rng.h"
#include "estimation/envmap.h"
#include "estimation/portal.h"
#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"
#include "estimation/transport.h"

namespace lp {

/// `lightprobe render`'s bounce cap: a guard, Russian roulette ends the paths (what it loses:
/// Cycles.TheBounceCapLosesLittleLight, docs/benchmarks.md).
inline constexpr int kRenderBounces = 8;

struct TracerOptions {
  int spp = 96;                  ///< camera samples per pixel (sub-pixel jitter)
  /// Surface interactions per path at most (1 = direct light only); Russian roulette runs
  /// from `roulette_after`. The cap cuts light (Cycles.TheBounceCapLosesLittleLight bounds
  /// it on a bright interreflecting box); the estimator's default, 5, relights the Cycles
  /// cornerbox best of 3, 5 and 8 (longer paths make the lights' columns noisier; figures in
  /// docs/benchmarks.md, session 21); `render` relights with kRenderBounces.
  int bounces = 5;
  int roulette_after = 2;        ///< Russian roulette from this bounce on
  double nee_floor = 0.05;       ///< epsilon: share of NEE samples spread by solid angle
  double min_throughput = 1e-4;  ///< paths whose throughput falls below this stop (negligible)
  std::uint64_t seed = 1;
  /// The lights' (VertexLight's) light at each path's first vertex: off, a render leaves a
  /// pixel's direct light from them to the caller (the clean render's guide traces it
  /// stratified over the pixel; estimation/render_denoise.h).
  bool first_vertex_lights = true;
  /// Checked (from the worker threads) before each chunk of 64 pixels; once it returns true
  /// the remaining pixels are skipped and the result is incomplete: the caller discards it.
  std::function<bool()> cancelled;
};

/// What the tracer left out or did, for the report.
struct TraceStats {
  std::int64_t pixels_traced = 0;
  std::int64_t pixels_skipped = 0;  ///< masked or invalid: not traced
  std::int64_t paths = 0;
  std::int64_t rays = 0;
  std::int64_t stopped_roulette = 0;
  std::int64_t stopped_negligible = 0;
  std::int64_t stopped_max_bounces = 0;
  double seconds = 0;
};

/// NEE importance over cells: q_j = (1-eps)*w_j/sum(w) + eps*Omega_j/Omega_reach, with
/// w_j = luminance(lambda_j)*Omega_j; cells with `reachable[j] == 0` get q_j = 0.
/// `lambda` may be empty (uniform by solid angle). With portals (a window's openings), a
/// share of the samples aims at a point uniform over their area instead (a one-sample
/// mixture: the direction's density is both strategies', Density).
class CellSampler {
 public:
  CellSampler(const EnvMap& env, const std::vector<double>& lambda, const std::vector<std::uint8_t>& reachable,
              double floor);
  int Sample(double u) const;
  /// Probability of choosing cell j (by the cells' strategy).
  double Probability(int j) const { return prob_[j]; }
  /// A `share` of the samples aims through `portals` (none: every sample by cell).
  void SetPortals(std::vector<Portal> portals, double share);
  bool HasPortals() const { return !portals_.empty(); }
  /// The density (per steradian) of drawing unit direction `w`, in cell `j`, from `origin`.
  double Density(const EnvMap& env, int j, const Eigen::Vector3d& origin, const Eigen::Vector3d& w) const;
  /// A direction from `origin` drawn with three uniform numbers (its cell in `cell`).
  Eigen::Vector3d SampleDirection(const EnvMap& env, const Eigen::Vector3d& origin, double u0, double u1, double u2,
                                  int* cell) const;

 private:
  std::vector<double> prob_, cdf_;
  std::vector<Portal> portals_;
  std::vector<double> portal_cdf_;  ///< by area
  double portal_share_ = 0, portal_area_ = 0;
};

/// Next-event estimation from a Lambertian surface point (shading normal `n`, geometric
/// normal `g`, shadow rays from `origin`, already off the surface): a cell drawn by
/// `sampler`, a direction uniform in it, and when it is above both normals and not
/// occluded (`visible`), its weight cos/pi x the power heuristic against cosine sampling /
/// the pdf. `traced`: a shadow ray was cast. Draws three numbers from `rng`.
struct NextEvent {
  int cell = 0;
  double weight = 0;
  bool traced = false, visible = false;
};
NextEvent SampleNextEvent(const RayTracer& scene, const EnvMap& env, const CellSampler& sampler,
                          const Eigen::Vector3d& n, const Eigen::Vector3d& g, const Eigen::Vector3d& origin, Rng& rng);

/// The power-heuristic weight of a cosine-sampled direction `w` from `origin` (cosine `cos_n`
/// to the shading normal) that escapes through cell `j`, against next-event estimation.
double EscapeWeight(const EnvMap& env, const CellSampler& sampler, int j, double cos_n, const Eigen::Vector3d& origin,
                    const Eigen::Vector3d& w);

/// Traces every valid pixel of every view and returns A (rows in view, pixel order).
TransportMatrix TraceTransport(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                               const CellSampler& sampler, const TracerOptions& options,
                               TraceStats* stats = nullptr);

/// Renders each view under per-cell radiance `lambda` (3*env.size()) with exactly
/// the paths TraceTransport would trace with the same sampler and options; pixels
/// that are not valid are traced too when `all_pixels` is set (else left 0).
std::vector<ImageRGB> RenderEnvironment(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                                        const std::vector<double>& lambda, const CellSampler& sampler,
                                        const TracerOptions& options, bool all_pixels,
                                        TraceStats* stats = nullptr);

/// Light from sources other than the map reaching a path vertex (`hit`, shadow rays from
/// `origin`): the radiance factor that, times the vertex's throughput x albedo / pi, the
/// pixel receives (e.g. I cos / d^2 x visibility for a point light). `key` is distinct per
/// vertex of each sample (for deterministic jitter); `rays` counts the shadow rays it casts.
using VertexLight = std::function<Eigen::Vector3d(const SurfacePoint& hit, const Eigen::Vector3d& origin,
                                                  std::uint64_t key, std::int64_t& rays)>;

/// The radiance the camera sees leave the surface it hits by the surface's own glow (an
/// emitter's; the hit's geometric normal faces the camera).
using SeenLight = std::function<Eigen::Vector3d(const SurfacePoint& hit)>;

/// The same render with `lights` added at every vertex of the same paths (one pass for the
/// map and the lights; see RenderLighting in light_render.h), and `seen` at each path's
/// first vertex.
std::vector<ImageRGB> RenderEnvironment(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                                        const std::vector<double>& lambda, const CellSampler& sampler,
                                        const TracerOptions& options, bool all_pixels, const VertexLight& lights,
                                        TraceStats* stats = nullptr, const SeenLight& seen = SeenLight());

}  // namespace lp
