#pragma once
/// Meshes made lighter for drawing: the viewer draws a coarse copy while the view moves.
#include <vector>

#include <Eigen/Core>

#include "scene/mesh.h"

namespace lp {

/// A coarse version for display: vertices clustered on a grid of cubes of side `cell`
/// (metres), each cluster one vertex at its mean position with the mean normal and albedo;
/// triangles that collapse are dropped. `cluster_of` (optional) receives each input
/// vertex's output vertex, to carry per-vertex values over (AverageOverClusters).
Mesh ClusterMesh(const Mesh& mesh, float cell, std::vector<int>* cluster_of = nullptr);

/// The coarse mesh with at most about `max_triangles` triangles (the cell is grown until
/// it fits); the mesh itself when it already does.
Mesh SimplifyForDisplay(const Mesh& mesh, int max_triangles, std::vector<int>* cluster_of);

/// Per-output-vertex mean of `values` over the input vertices of each cluster.
std::vector<Eigen::Vector3f> AverageOverClusters(const std::vector<Eigen::Vector3f>& values,
                                                 const std::vector<int>& cluster_of, int clusters);

}  // namespace lp
