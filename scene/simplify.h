#pragma once
/// A coarser copy of a mesh for tracing (docs/method.md, "The traced mesh"): a
/// reconstruction's mesh has vertices every voxel, far finer than the pixels of the views
/// the estimator fits, and every ray and every de-lit vertex pays for them.
#include <vector>

#include "scene/camera.h"
#include "scene/mesh.h"

namespace lp {

/// A mesh clustered on a grid, and where each vertex of the source went.
struct ClusteredMesh {
  Mesh mesh;
  std::vector<int> cluster;  ///< per source vertex: its vertex in `mesh` (-1: used by no triangle)
};

/// Vertex clustering on a grid of `cell` metres (Rossignac and Borrel 1993): the vertices in
/// one cell become one vertex, placed where the summed squared distance to the planes of
/// its triangles is least (Lindstrom 2000; corners and edges stay where they were, flat
/// parts take the cluster's mean), kept within the cell and a half around it, else the
/// mean. Albedo, colours seen and normals are the cluster's means (normals normalized; zero
/// where they cancel, as in a thin sheet folded into one cell: SanitizeMesh replaces those).
/// Triangles whose corners fall into fewer than three clusters vanish, as do repeats.
/// Throws InputError when nothing is left (a cell larger than the mesh).
ClusteredMesh ClusterVertices(const Mesh& mesh, float cell);

/// Per vertex of `mesh`, the length (m) one pixel spans at that vertex in the view where it
/// is nearest in pixel terms (depth / focal length, over the views whose image it projects
/// into; occlusion ignored); infinity for a vertex no view's frustum holds.
std::vector<float> PixelFootprints(const Mesh& mesh, const std::vector<Camera>& cameras);

/// The `q`-quantile (0..1) of the finite values of `v`; 0 when none is finite.
float FiniteQuantile(std::vector<float> v, double q);

/// The median length of the mesh's edges (each triangle's three, once per triangle).
float MedianEdgeLength(const Mesh& mesh);

/// The summed area of the mesh's triangles (m^2).
double MeshArea(const Mesh& mesh);

}  // namespace lp
