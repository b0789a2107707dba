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

/// Into how many parts a row's paths are dealt (ShadingVertices::part): the lights refitted on
/// each give kPathParts - 1 degrees of freedom for their Monte Carlo spread (two halves give
/// one: a spread along a single direction; docs/benchmarks.md, session 38).
constexpr int kPathParts = 4;

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
  /// The half of the row's paths the vertex's path is in: +1 (the even samples), -1 (the odd
  /// ones) or 0 (neither: the last of an odd count). A column's two halves differ by the sum
  /// of its terms so signed, whose square estimates the column's Monte Carlo variance
  /// (ColumnRow, LightFitProblem). Empty: not kept (no variance is estimated).
  std::vector<std::int8_t> half;
  /// The part of the row's paths the vertex's path is in: its sample's index mod kPathParts,
  /// or -1 (the last samples of a count that is not a multiple of kPathParts). The lights
  /// refitted on each part apart spread as their Monte Carlo noise does (PartsCovariance).
  /// Empty: not kept.
  std::vector<std::int8_t> part;
  std::size_t rows() const { return row_start.size() - 1; }
  /// The vertex's half (0 when not kept).
  int Half(std::size_t k) const { return half.empty() ? 0 : half[k]; }
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

/// The vertices of one half of each row's paths (`half`: +1 or -1; ShadingVertices::half),
/// their weights doubled: what a gathering of half the paths would hold. Needs `half` kept.
ShadingVertices HalfOf(const ShadingVertices& v, int half);

/// The vertices of one part of each row's paths (`part`: 0 .. kPathParts - 1;
/// ShadingVertices::part), their weights times kPathParts: what a gathering of that share of
/// the paths would hold (its halves 0). Needs `part` kept.
ShadingVertices PartOf(const ShadingVertices& v, int part);

/// Where a light's column on shading vertices goes: `value` (3 per row) and, each when
/// given, its derivative with respect to the light's shape (9 per row: [9*row + 3*c + k]),
/// the difference of its two halves (ShadingVertices::half; 3 per row) and that
/// difference's derivative (9 per row).
struct ColumnOut {
  std::vector<float>* value = nullptr;
  std::vector<float>* jacobian = nullptr;
  std::vector<float>* spread = nullptr;
  std::vector<float>* spread_jacobian = nullptr;
  /// Each given output sized for `rows` and zeroed.
  void Assign(std::size_t rows) const {
    value->assign(3 * rows, 0.0f);
    if (jacobian) jacobian->assign(9 * rows, 0.0f);
    if (spread) spread->assign(3 * rows, 0.0f);
    if (spread_jacobian) spread_jacobian->assign(9 * rows, 0.0f);
  }
};

/// A column's row summed vertex by vertex: the sum and its derivative, and the same with each
/// term signed by its path's half (ColumnOut's spread).
struct ColumnRow {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), spread = Eigen::Vector3d::Zero();
  Eigen::Matrix3d jac = Eigen::Matrix3d::Zero(), spread_jac = Eigen::Matrix3d::Zero();  ///< (channel, coordinate)
  void Add(int half, const Eigen::Vector3d& value) {
    sum += value;
    spread += half * value;
  }
  void AddDerivative(int half, const Eigen::Matrix3d& d) {
    jac += d;
    spread_jac += half * d;
  }
  /// Writes row `r` (as floats) to each output given.
  void Store(std::size_t r, const ColumnOut& out) const {
    for (int c = 0; c < 3; ++c) {
      (*out.value)[3 * r + c] = static_cast<float>(sum[c]);
      if (out.spread) (*out.spread)[3 * r + c] = static_cast<float>(spread[c]);
      for (int a = 0; a < 3; ++a) {
        if (out.jacobian) (*out.jacobian)[9 * r + 3 * c + a] = static_cast<float>(jac(c, a));
        if (out.spread_jacobian) (*out.spread_jacobian)[9 * r + 3 * c + a] = static_cast<float>(spread_jac(c, a));
      }
    }
  }
};

}  // namespace lp
