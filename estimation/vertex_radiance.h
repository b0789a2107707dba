#pragma once
/// Outgoing radiance of every mesh vertex under an estimate's lighting (its map and lights), refined progressively:
/// what the viewer's "lit" shading shows. Each Refine() adds samples per vertex of a path
/// (up to `bounces` surface interactions, Lambertian albedo; at each, next-event estimation
/// towards a cell drawn by the estimate's brightness and cosine sampling, combined by the
/// power heuristic, as the path tracer; and a shadow ray to each light) and averages
/// them with the earlier ones, so the picture sharpens while the user looks.
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "estimation/envmap.h"
#include "estimation/lighting.h"
#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"

namespace lp {

class CellSampler;
struct SurfaceFilter;

/// The lit shading as shown: per vertex radiance with its Monte Carlo noise smoothed out
/// over the surface, and how much noise is left.
struct LitShading {
  /// Albedo times the smoothed incident radiance, plus a glowing surface's own (an emitter's
  /// radiance on the side of the vertex's normal).
  std::vector<Eigen::Vector3f> radiance;
  /// The relative noise left: the RMS over the traced vertices of half the difference of
  /// the two halves' smoothed radiances (the even and the odd samples, independent: the
  /// noise of their mean), over the mean radiance. The smoothing's blur is not in it.
  double noise = 0;
};

class VertexRadiance {
 public:
  /// `lighting`: the estimate (its map 3 * env.size() linear radiances, its lights in the
  /// same units); `bounces` >= 1 (1 = direct light only). `scene` must outlive this object
  /// and be built from the mesh whose vertices are shaded (its normals orient the
  /// hemispheres).
  VertexRadiance(const RayTracer& scene, const EnvMap& env, Lighting lighting, int bounces = 3,
                 std::uint64_t seed = 1);
  ~VertexRadiance();

  /// Aims a `share` of the map's next events through `portals` (a window's openings).
  void SetPortals(std::vector<Portal> portals, double share) { sampler_->SetPortals(std::move(portals), share); }
  /// Draws each vertex's first bounce from a two-dimensional Sobol sequence, shifted at
  /// random per vertex (and apart for the even and the odd samples), instead of independent
  /// points: unbiased, and on the demo bundle and the Cycles cornerbox about half the
  /// variance at 64-2,048 samples (the viewer's lit shading; the albedo pass keeps
  /// independent points). Set it before the first Refine.
  void SetStratified(bool on) { stratified_ = on; }
  /// Adds `samples` paths per vertex (parallel over vertices; deterministic per seed).
  void Refine(int samples);
  /// The same for the vertices `which` marks only (one entry per vertex): each vertex's
  /// paths continue its own sequence, so a vertex refined k times in all has the paths it
  /// would have from Refine(k). Clean() then no longer applies (its halves need one count).
  void Refine(int samples, const std::vector<std::uint8_t>& which);
  /// Mean outgoing radiance per vertex (linear RGB, the estimate's units): albedo times the
  /// mean incident radiance over the cosine-weighted hemisphere.
  std::vector<Eigen::Vector3f> Radiance() const;
  /// Mean incident radiance per vertex over the cosine-weighted hemisphere, as a grey
  /// level (the mean of its channels): irradiance / pi.
  std::vector<float> Irradiance() const;
  /// Per vertex, the variance of Irradiance()'s value as a mean of its paths: the grey
  /// level's sample variance over the vertex's paths over their count (0 with fewer than 2).
  std::vector<float> IrradianceVariance() const;
  /// Radiance() with the incident radiance smoothed over the surface (SmoothOverSurface:
  /// shadows' edges blur by a few `filter.spacing`s) and its noise left, from the even and
  /// the odd samples apart. Needs an even samples() >= 2.
  LitShading Clean(const SurfaceFilter& filter) const;
  /// The paths each vertex has had (with Refine(samples) alone, samples() for every one).
  int samples() const { return samples_; }
  int samples(std::size_t vertex) const { return count_[vertex]; }

 private:
  /// Refines every vertex, or those `which` marks (one entry per vertex) where given.
  void RefineWhere(int samples, const std::uint8_t* which);
  void RefineVertex(std::size_t v, int samples);

  const RayTracer& scene_;
  const EnvMap& env_;
  Lighting lighting_;
  int bounces_;
  std::uint64_t seed_;
  int samples_ = 0;       ///< the paths of every vertex, or -1 once Refine(samples, which) ran
  std::vector<int> count_;  ///< per vertex, its paths
  bool stratified_ = false;
  std::unique_ptr<CellSampler> sampler_;  ///< NEE over cells, by the estimate's brightness
  /// Per vertex, the lights' irradiance / pi at the vertex itself, where that is the same for
  /// every sample (points and directions without extent: one shadow ray, no randomness):
  /// traced once (NaN until then). Empty where it is not (or there is no light).
  std::vector<Eigen::Vector3d> at_vertex_;
  std::vector<Eigen::Vector3d> sum_;  ///< per vertex, incident radiance summed over samples
  std::vector<Eigen::Vector3d> odd_;  ///< the same over the odd samples only
  std::vector<double> square_;        ///< per vertex, the grey level's square summed over samples
};

/// Per vertex: PixelError(radiance, observed) / WhiteLevel(view) against the nearest view
/// that sees the vertex (inside its image, a valid pixel, not occluded: the first hit
/// from its camera lies within 2 % of the distance); NaN where no view sees it.
std::vector<float> VertexPhotometricError(const RayTracer& scene, const std::vector<View>& views,
                                          const std::vector<Eigen::Vector3f>& radiance);

}  // namespace lp
