#include "scene/surface_filter.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/parallel.h"

namespace lp {

namespace {

/// The mesh's vertex adjacency with each edge's weight (compressed rows).
struct Adjacency {
  std::vector<std::size_t> start;  ///< per vertex, into `to` / `weight`; size n + 1
  std::vector<int> to;
  std::vector<float> weight;
};

Adjacency WeightedAdjacency(const Mesh& mesh, const SurfaceFilter& f) {
  const std::size_t n = mesh.positions.size();
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(mesh.triangles.size() * 6);
  for (const Eigen::Vector3i& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      if (a == b) continue;
      pairs.emplace_back(a, b);
      pairs.emplace_back(b, a);
    }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  Adjacency adj;
  adj.start.assign(n + 1, 0);
  for (const auto& p : pairs) ++adj.start[p.first + 1];
  for (std::size_t v = 0; v < n; ++v) adj.start[v + 1] += adj.start[v];
  adj.to.resize(pairs.size());
  adj.weight.resize(pairs.size());
  const bool normals = mesh.normals.size() == n;
  const double inv = 1 / (2 * f.spacing * f.spacing);
  for (std::size_t e = 0; e < pairs.size(); ++e) {
    const auto [a, b] = pairs[e];
    adj.to[e] = b;
    const double d2 = (mesh.positions[a] - mesh.positions[b]).squaredNorm();
    const bool alike = normals && mesh.normals[a].dot(mesh.normals[b]) >= f.min_normal_cosine;
    adj.weight[e] = alike ? static_cast<float>(std::exp(-d2 * inv)) : 0.f;
  }
  return adj;
}

}  // namespace

std::vector<Eigen::Vector3f> SmoothOverSurface(const Mesh& mesh, const std::vector<Eigen::Vector3f>& values,
                                               const SurfaceFilter& filter) {
  LP_CHECK(values.size() == mesh.positions.size(),
           "SmoothOverSurface: " << values.size() << " values for " << mesh.positions.size() << " vertices");
  LP_CHECK(filter.spacing > 0 && filter.iterations >= 0, "SmoothOverSurface: spacing " << filter.spacing);
  const Adjacency adj = WeightedAdjacency(mesh, filter);
  std::vector<Eigen::Vector3f> now = values, next(values.size());
  for (int it = 0; it < filter.iterations; ++it) {
    ParallelForChunks(0, now.size(), 4096, [&](std::size_t b, std::size_t e) {
      for (std::size_t v = b; v < e; ++v) {
        Eigen::Vector3d sum = now[v].cast<double>();
        double w = 1;
        for (std::size_t k = adj.start[v]; k < adj.start[v + 1]; ++k) {
          sum += adj.weight[k] * now[adj.to[k]].cast<double>();
          w += adj.weight[k];
        }
        next[v] = (sum / w).cast<float>();
      }
    });
    now.swap(next);
  }
  return now;
}

}  // namespace lp
