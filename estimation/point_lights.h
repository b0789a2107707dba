#pragma once
/// Near lights (docs/method.md, "Point lights"): lamps at 3D positions beside the
/// environment map, as further columns of the transport matrix. The camera paths' shading
/// vertices (where light arriving at a surface reaches a pixel, with the path's weight) are
/// gathered once; a point light's column at any position is then next-event estimation
/// from those vertices to it (a delta light: one shadow ray each, no MIS), and so is the
/// column's derivative with respect to the position, analytically (visibility held fixed).
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "estimation/directional_light.h"
#include "estimation/envmap.h"
#include "estimation/point_light.h"
#include "estimation/path_tracer.h"
#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"

namespace lp {

/// The shading vertices of camera paths, row by row in the transport matrix's order (the
/// valid pixels of each view, or every pixel when gathered with all_pixels).
struct ShadingVertices {
  std::vector<std::int64_t> row_start{0};  ///< rows()+1 offsets
  std::vector<Eigen::Vector3f> position;   ///< just off the surface, on the lit side
  std::vector<Eigen::Vector3f> normal;     ///< shading normal
  std::vector<Eigen::Vector3f> geometric;  ///< geometric normal (same side)
  /// Path throughput x albedo / (pi x samples per pixel): the pixel receives
  /// weight x cos / d^2 x I from a point light of intensity I at distance d.
  std::vector<Eigen::Vector3f> weight;
  std::size_t rows() const { return row_start.size() - 1; }
  std::size_t size() const { return position.size(); }
};

/// Traces options.spp cosine-sampled paths per pixel (options.bounces surface interactions,
/// Russian roulette as TraceTransport) and keeps each path's shading vertices.
ShadingVertices GatherShadingVertices(const RayTracer& scene, const std::vector<View>& views,
                                      const TracerOptions& options, bool all_pixels = false,
                                      TraceStats* stats = nullptr);

/// Sample-count-weighted union of two gatherings over the same rows (each vertex's weight
/// scaled by its gathering's share of the samples), like Combine for transport matrices.
ShadingVertices Combine(const ShadingVertices& a, double a_samples, const ShadingVertices& b, double b_samples);

/// Shadow rays per vertex from a column towards a light with a radius (its disc, stratified).
constexpr int kSphereShadowRays = 4;

/// The share of a spherical light of `radius` centred at q that `p` sees (l, d: the unit
/// direction and distance from p to q): one shadow ray to q for a point (radius 0), else
/// `rays` shadow rays to jittered stratified points of the disc of `radius` facing p, the
/// pattern drawn from a hash of `key` (deterministic: common random numbers across positions
/// and radii; the renderers pass a key per sample and 1 ray). The cosine and 1/d^2 stay the
/// centre's: exact for a uniform sphere wholly seen and above the horizon, so the radius
/// only softens shadows.
double SphereVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& q, double radius,
                        const Eigen::Vector3d& l, double d, std::uint64_t key, int rays = kSphereShadowRays);

/// The unit-intensity column of a point light at `q` (of `radius`: soft shadows): out[3*row
/// + c]. When `jacobian` is given it receives d out[3*row + c] / d q_k at [9*row + 3*c + k]
/// (visibility held fixed).
void PointLightColumn(const RayTracer& scene, const ShadingVertices& vertices, const Eigen::Vector3d& q,
                      std::vector<float>* out, std::vector<float>* jacobian = nullptr, double radius = 0);

/// The column of a directional light of unit irradiance (on a surface facing it) from unit
/// world direction `towards` (towards the light): out[3*row + c]. When `jacobian` is given
/// it receives the derivative with respect to the direction moved on the unit sphere
/// (towards + delta, normalized; visibility held fixed) at [9*row + 3*c + k]. With an
/// `angular_radius` (a disc of that half-angle) each vertex sends kSphereShadowRays shadow
/// rays across it (ConeVisibility, a fixed pattern per vertex).
void DirectionalLightColumn(const RayTracer& scene, const ShadingVertices& vertices, const Eigen::Vector3d& towards,
                            std::vector<float>* out, std::vector<float>* jacobian = nullptr, double angular_radius = 0);

/// The share of a light of `angular_radius` (a disc around unit direction l, as seen from
/// p) that p sees: one shadow ray along l when sharp, else `rays` jittered stratified rays
/// across the disc, the pattern drawn from a hash of `key` (as SphereVisibility's).
double ConeVisibility(const RayTracer& scene, const Eigen::Vector3d& p, const Eigen::Vector3d& l, double angular_radius,
                      std::uint64_t key, int rays = kSphereShadowRays);

/// Renders each view under the map (`lambda`, 3 per cell of `env`, NEE by `sampler`), the
/// point lights and the directional lights together, in one pass: at every vertex of the
/// map's paths, one shadow ray to each light (a jittered point of its disc). The same as
/// RenderEnvironment plus RenderPointLights, for about the map's cost alone.
std::vector<ImageRGB> RenderLighting(const RayTracer& scene, const EnvMap& env, const std::vector<double>& lambda,
                                     const CellSampler& sampler, const std::vector<PointLight>& lights,
                                     const std::vector<DirectionalLight>& directional, const std::vector<View>& views,
                                     const TracerOptions& options, bool all_pixels, TraceStats* stats = nullptr);

/// Renders each view under the point lights and the directional ones (every pixel when
/// `all_pixels`, else only the valid ones): the forward model of the columns above, with
/// options.spp paths per pixel.
std::vector<ImageRGB> RenderPointLights(const RayTracer& scene, const std::vector<View>& views,
                                        const std::vector<PointLight>& lights, const TracerOptions& options,
                                        bool all_pixels, TraceStats* stats = nullptr,
                                        const std::vector<DirectionalLight>& directional = {});

}  // namespace lp

namespace lp {

/// Where the estimator first looks for lamps: shells of directions (a coarse ring map
/// around `up`, `rings` rings) at each of `radii` (multiples of the scene's bounding radius)
/// around the scene's centre. Free space and the space beyond the scan alike: a candidate
/// inside geometry or behind a wall lights no observed pixel and drops out of the problem.
std::vector<Eigen::Vector3d> CandidatePositions(const Eigen::Vector3d& centre, double radius,
                                                const Eigen::Vector3d& up, int rings = 7,
                                                const std::vector<double>& radii = {0.35, 0.6, 1.0, 1.6});

/// sum_i sigma^2/2 log(1 + r_i^2/sigma^2): the Cauchy loss of residuals `r`.
double CauchyLoss(const std::vector<double>& r, double sigma);

/// The robust objective of point lights on fixed shading vertices, the rest of the image
/// (`base`: the environment's render, 3 per row) held fixed:
///   E = sum rho_sigma(y - base - sum_k I_k . c(q_k)) + sum_k alpha log(1 + beta sum_c I_kc).
struct PointFitProblem {
  const RayTracer* scene = nullptr;
  const ShadingVertices* vertices = nullptr;
  const std::vector<double>* y = nullptr;     ///< 3 per row
  const std::vector<double>* base = nullptr;  ///< 3 per row
  double sigma = 0.5, alpha = 3, beta = 1;
  /// E at these lights; `sse`, when given, receives the sum of squared residuals.
  double Value(const std::vector<PointLight>& lights, double* sse = nullptr) const;
  /// The same with the lights' unit columns given (as PointLightColumn makes them on these
  /// vertices: e.g. from a cache).
  double Value(const std::vector<PointLight>& lights, const std::vector<std::vector<float>>& columns,
               double* sse = nullptr) const;
};
/// Every stride-th row of a fitting problem (stride = rows / max_rows rounded up; 1, the
/// problem itself, when it has no more): its vertices, observations and base, the activation
/// penalty divided by the stride so that it weighs against the data term as on all rows.
/// Where a share of the rows is enough to move the lights (each column on it costs that
/// share); its E times the stride estimates the whole problem's.
struct PointFitSubset {
  PointFitSubset(const PointFitProblem& full, std::size_t max_rows);
  PointFitSubset(const PointFitSubset&) = delete;
  PointFitSubset& operator=(const PointFitSubset&) = delete;
  int stride = 1;
  ShadingVertices vertices;
  std::vector<double> y, base;
  PointFitProblem problem;
};

/// Levenberg-Marquardt on the lights' positions and intensities together (iteratively
/// reweighted for the Cauchy loss, the analytical derivative of the direct term, intensities
/// kept >= 0); each step is taken only if E falls. Returns the iterations taken; `lights`
/// holds the best found. `log(iteration, E, sum of squared residuals, lights)` is called
/// after each accepted step.
int RefinePointLights(
    const PointFitProblem& problem, std::vector<PointLight>* lights, int max_iterations = 12,
    const std::function<void(int, double, double, const std::vector<PointLight>&)>& log = {});

/// A compass search for each light's position in turn (steps of `start` times its distance
/// from `centre` along the axes, halved when no step lowers the energy, down to `stop`
/// times it; at most `max_evaluations` columns a light, besides one for each other light),
/// its intensity refitted at each place by reweighted least squares, the other lights held:
/// the shadows' edges move with the light, which RefinePointLights' derivative (visibility
/// held fixed) cannot see. A light is changed only where it moves (a PointFitSubset's
/// problem makes it look at a share of the rows). Returns the moves taken; `log` is called
/// after each (light k's energy and the sum of squared residuals).
int SearchPointLights(const PointFitProblem& problem, std::vector<PointLight>* lights, const Eigen::Vector3d& centre,
                      double start = 0.02, double stop = 0.002, int max_evaluations = 60,
                      const std::function<void(int, double, double, const std::vector<PointLight>&)>& log = {});

/// The same for one directional light (its direction on the unit sphere and its
/// irradiance; `problem.alpha` its activation penalty), the rest of the image held fixed.
int RefineDirectionalLight(const PointFitProblem& problem, DirectionalLight* light, int max_iterations = 12,
                           const std::function<void(int, double, double, const DirectionalLight&)>& log = {});

/// A compass search for a directional light's direction on the sphere (steps of start_deg
/// across it, halved when no step lowers the energy, down to stop_deg), its irradiance
/// refitted by reweighted least squares at each: the shadows' edges move with the
/// direction, which RefineDirectionalLight's derivative (visibility held fixed) cannot see.
/// Returns the moves taken; `log` is called after each.
int SearchDirectionalLight(const PointFitProblem& problem, DirectionalLight* light, double start_deg = 2,
                           double stop_deg = 0.05,
                           const std::function<void(int, double, double, const DirectionalLight&)>& log = {});

/// The widest angular radius FitAngularRadius tries (degrees).
constexpr double kMaxAngularRadiusDeg = 8;

/// The angular radius (soft shadows) of a directional light on a grid (0 and 0.25 to
/// kMaxAngularRadiusDeg, doubling), its irradiance refitted at each, the rest held: the
/// lowest energy wins when it beats the sharp light's by 0.5 %. Returns the radius (radians).
double FitAngularRadius(const PointFitProblem& problem, DirectionalLight* light);

}  // namespace lp
