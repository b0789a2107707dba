#include "ui/mesh_display.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

namespace lp {

Mesh ClusterMesh(const Mesh& mesh, float cell, std::vector<int>* cluster_of) {
  Eigen::Vector3f lo, hi;
  MeshBounds(mesh, &lo, &hi);
  std::unordered_map<std::int64_t, int> index;
  std::vector<int> of(mesh.positions.size(), -1);
  Mesh out;
  std::vector<int> count;
  const bool normals = mesh.normals.size() == mesh.positions.size();
  const bool albedo = mesh.albedo.size() == mesh.positions.size();
  std::vector<char> used(mesh.positions.size(), 0);
  for (const Eigen::Vector3i& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) used[t[k]] = 1;
  // 21 bits per axis: a cell is at least 1/2^21 of the mesh's extent.
  const float extent = (hi - lo).maxCoeff();
  cell = std::max(cell, extent / 2097000.f);
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    if (!used[v]) continue;  // outside the bounds; dropped with the triangles it is not in
    const Eigen::Vector3f q = (mesh.positions[v] - lo) / cell;
    if (!q.allFinite()) continue;
    const std::int64_t key = (static_cast<std::int64_t>(q.x()) << 42) | (static_cast<std::int64_t>(q.y()) << 21) |
                             static_cast<std::int64_t>(q.z());
    auto [it, fresh] = index.emplace(key, static_cast<int>(out.positions.size()));
    if (fresh) {
      out.positions.push_back(Eigen::Vector3f::Zero());
      out.normals.push_back(Eigen::Vector3f::Zero());
      out.albedo.push_back(Eigen::Vector3f::Zero());
      count.push_back(0);
    }
    const int c = it->second;
    of[v] = c;
    out.positions[c] += mesh.positions[v];
    if (normals) out.normals[c] += mesh.normals[v];
    out.albedo[c] += albedo ? mesh.albedo[v] : Eigen::Vector3f::Constant(0.5f);
    ++count[c];
  }
  for (std::size_t c = 0; c < count.size(); ++c) {
    out.positions[c] /= static_cast<float>(count[c]);
    out.albedo[c] /= static_cast<float>(count[c]);
    const float n = out.normals[c].norm();
    out.normals[c] = n > 0 ? Eigen::Vector3f(out.normals[c] / n) : Eigen::Vector3f::UnitZ();
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3i m(of[t[0]], of[t[1]], of[t[2]]);
    if (m.minCoeff() < 0 || m[0] == m[1] || m[1] == m[2] || m[0] == m[2]) continue;
    out.triangles.push_back(m);
  }
  if (!normals) ComputeVertexNormals(&out);
  if (cluster_of) *cluster_of = std::move(of);
  return out;
}

Mesh SimplifyForDisplay(const Mesh& mesh, int max_triangles, std::vector<int>* cluster_of) {
  if (static_cast<int>(mesh.triangles.size()) <= max_triangles) {
    if (cluster_of) {
      cluster_of->resize(mesh.positions.size());
      std::iota(cluster_of->begin(), cluster_of->end(), 0);
    }
    return mesh;
  }
  Eigen::Vector3f lo, hi;
  MeshBounds(mesh, &lo, &hi);
  // A surface's triangle count falls with the square of the cell: start from the mean edge
  // length scaled by the reduction wanted, grow by 1.3 until it fits.
  double edge = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) edge += (mesh.positions[t[1]] - mesh.positions[t[0]]).norm();
  float cell = static_cast<float>(edge / mesh.triangles.size() *
                                  std::sqrt(static_cast<double>(mesh.triangles.size()) / max_triangles));
  for (int i = 0; i < 20; ++i, cell *= 1.3f) {
    Mesh out = ClusterMesh(mesh, cell, cluster_of);
    if (static_cast<int>(out.triangles.size()) <= max_triangles) return out;
  }
  return ClusterMesh(mesh, (hi - lo).maxCoeff(), cluster_of);
}

std::vector<Eigen::Vector3f> AverageOverClusters(const std::vector<Eigen::Vector3f>& values,
                                                 const std::vector<int>& cluster_of, int clusters) {
  std::vector<Eigen::Vector3f> out(clusters, Eigen::Vector3f::Zero());
  std::vector<int> count(clusters, 0);
  for (std::size_t v = 0; v < values.size() && v < cluster_of.size(); ++v) {
    const int c = cluster_of[v];
    if (c < 0 || c >= clusters || !values[v].allFinite()) continue;
    out[c] += values[v];
    ++count[c];
  }
  for (int c = 0; c < clusters; ++c)
    if (count[c] > 0) out[c] /= static_cast<float>(count[c]);
  return out;
}

}  // namespace lp
