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
};

/// Each vertex's value averaged with its neighbours' along the mesh's edges, `iterations`
/// times (a diffusion on the surface, edge-aware by the normals). Vertices with no usable
/// normal keep their value. Deterministic; parallel over vertices.
std::vector<Eigen::Vector3f> SmoothOverSurface(const Mesh& mesh, const std::vector<Eigen::Vector3f>& values,
                                               const SurfaceFilter& filter = {});

}  // namespace lp
