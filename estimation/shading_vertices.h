#pragma once
/// The shading vertices of camera paths (docs/method.md, "Point lights"): where light
/// arriving at a surface reaches a pixel, with the path's weight. Gathered once a round;
/// every light kind's column at any shape is then next-event estimation from them
/// (estimation/lights/), and so is its derivative with respect to the shape.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

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
  /// The weight the camera sees the vertex itself with: 1 / samples per pixel for a path's
  /// first vertex (the surface the pixel sees), 0 for the vertices after it (a glowing
  /// surface's own radiance reaches the pixel with it: EmitterLight). Empty: not kept.
  std::vector<float> camera;
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

/// Stores a column's row `r`: `sum` (per channel) at out[3*r + c] and, when `jacobian` is
/// given, `jac` (channel, coordinate) at [9*r + 3*c + a], as floats.
inline void StoreColumnRow(std::size_t r, const Eigen::Vector3d& sum, const Eigen::Matrix3d& jac,
                           std::vector<float>* out, std::vector<float>* jacobian) {
  for (int c = 0; c < 3; ++c) (*out)[3 * r + c] = static_cast<float>(sum[c]);
  if (jacobian)
    for (int c = 0; c < 3; ++c)
      for (int a = 0; a < 3; ++a) (*jacobian)[9 * r + 3 * c + a] = static_cast<float>(jac(c, a));
}

}  // namespace lp
