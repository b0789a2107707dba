#pragma once
/// Smoothing of per-vertex values over a mesh's surface: what takes a Monte Carlo
/// estimate's per-vertex noise out of the lit shading (irradiance varies slowly across a
/// surface; its noise varies from one vertex to the next).
#include <vector>

#include <Eigen/Core>

#include "scene/mesh.h"

namespace lp {

struct SurfaceFilter {
  /// Metres: a neighbour across an edge of length d weighs exp(-d^2 / (2 spacing^2))
  /// against the vertex's own 1, so long edges (a coarse mesh's) carry almost nothing.
  double spacing = 0.01;
  int iterations = 8;  ///< Jacobi steps: the blur's width grows as spacing * sqrt(iterations)
  /// Neighbours whose normals' cosine is below this are not averaged (a crease, a corner).
  double min_normal_cosine = 0.9;
  /// FitAffineOverSurface's ridges on the fit's slopes, in the units of the features'
  /// spread: square metres for the place, squared normal differences for the normal. They
  /// hold a slope the neighbours cannot tell (a flat patch's spread along its normal, a
  /// patch whose normals are all alike) at 0 instead of at the noise's.
  double place_ridge = 1e-6;
  double normal_ridge = 1e-3;
};

/// Each vertex's value averaged with its neighbours' along the mesh's edges, `iterations`
/// times (a diffusion on the surface, edge-aware by the normals). Vertices with no usable
/// normal keep their value. Deterministic; parallel over vertices.
std::vector<Eigen::Vector3f> SmoothOverSurface(const Mesh& mesh, const std::vector<Eigen::Vector3f>& values,
                                               const SurfaceFilter& filter = {});
/// Each vertex's values replaced by a local fit affine in the place and the normal,
/// evaluated at the vertex: a weighted least-squares fit over the neighbours, weighted as
/// SmoothOverSurface averages them (its diffusion of the fit's moments). Values affine in the
/// place and the normal come back as they were (the ridges aside), where SmoothOverSurface
/// would mix the values of neighbours whose normals differ (a scan's) and, beside a crease
/// or a border, of neighbours on one side. Every field is fitted on the same neighbours and
/// weights (one diffusion). Vertices with no usable normal keep their values.
void FitAffineOverSurface(const Mesh& mesh, const std::vector<std::vector<Eigen::Vector3f>*>& fields,
                          const SurfaceFilter& filter = {});

}  // namespace lp
