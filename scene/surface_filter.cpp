#include "scene/surface_filter.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

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

/// SmoothOverSurface's diffusion of `channels` values per vertex, stored as T.
template <typename T>
std::vector<T> Diffuse(const Mesh& mesh, const Adjacency& adj, std::vector<T> now, std::size_t c, int iterations) {
  std::vector<T> next(now.size());
  for (int it = 0; it < iterations; ++it) {
    ParallelForChunks(0, mesh.positions.size(), 4096, [&](std::size_t b, std::size_t e) {
      std::vector<double> sum(c);
      for (std::size_t v = b; v < e; ++v) {
        for (std::size_t k = 0; k < c; ++k) sum[k] = now[v * c + k];
        double w = 1;
        for (std::size_t j = adj.start[v]; j < adj.start[v + 1]; ++j) {
          const T* u = &now[static_cast<std::size_t>(adj.to[j]) * c];
          for (std::size_t k = 0; k < c; ++k) sum[k] += adj.weight[j] * u[k];
          w += adj.weight[j];
        }
        for (std::size_t k = 0; k < c; ++k) next[v * c + k] = static_cast<T>(sum[k] / w);
      }
    });
    now.swap(next);
  }
  return now;
}

}  // namespace

std::vector<Eigen::Vector3f> SmoothOverSurface(const Mesh& mesh, const std::vector<Eigen::Vector3f>& values,
                                               const SurfaceFilter& filter) {
  LP_CHECK(values.size() == mesh.positions.size(),
           "SmoothOverSurface: " << values.size() << " values for " << mesh.positions.size() << " vertices");
  LP_CHECK(filter.spacing > 0 && filter.iterations >= 0, "SmoothOverSurface: spacing " << filter.spacing);
  std::vector<float> flat(3 * values.size());
  for (std::size_t v = 0; v < values.size(); ++v)
    for (int k = 0; k < 3; ++k) flat[3 * v + k] = values[v][k];
  flat = Diffuse(mesh, WeightedAdjacency(mesh, filter), std::move(flat), 3, filter.iterations);
  std::vector<Eigen::Vector3f> out(values.size());
  for (std::size_t v = 0; v < values.size(); ++v) out[v] = Eigen::Vector3f(flat[3 * v], flat[3 * v + 1], flat[3 * v + 2]);
  return out;
}

void FitAffineOverSurface(const Mesh& mesh, const std::vector<std::vector<Eigen::Vector3f>*>& fields,
                          const SurfaceFilter& filter) {
  constexpr int kF = 6;  // the place (about the mesh's centre), the normal
  constexpr int kMoments = kF + kF * (kF + 1) / 2, kPerChannel = 1 + kF;
  using Features = Eigen::Matrix<double, kF, 1>;
  const std::size_t n = mesh.positions.size();
  for (const auto* f : fields)
    LP_CHECK(f->size() == n, "FitAffineOverSurface: " << f->size() << " values for " << n << " vertices");
  LP_CHECK(filter.spacing > 0 && filter.iterations >= 0, "FitAffineOverSurface: spacing " << filter.spacing);
  const std::size_t channels = 3 * kPerChannel * fields.size();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3f& p : mesh.positions) centre += p.cast<double>();
  if (n > 0) centre /= static_cast<double>(n);
  const auto usable = [&](std::size_t v) { return v < mesh.normals.size() && mesh.normals[v].squaredNorm() > 0.5f; };
  const auto features = [&](std::size_t v) {
    Features f = Features::Zero();
    f.head<3>() = mesh.positions[v].cast<double>() - centre;
    if (usable(v)) f.tail<3>() = mesh.normals[v].cast<double>();
    return f;
  };
  // Per vertex, f and f fᵀ (its upper half) in double (a place's spread over the
  // neighbours is ~1e-4 m² beside its square's ~1 m²), and per field and channel y and f y.
  std::vector<double> fm(n * kMoments);
  std::vector<float> ym(n * channels);
  ParallelForChunks(0, n, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      const Features f = features(v);
      double* moments = &fm[v * kMoments];
      int k = 0;
      for (int a = 0; a < kF; ++a) moments[k++] = f[a];
      for (int a = 0; a < kF; ++a)
        for (int c = a; c < kF; ++c) moments[k++] = f[a] * f[c];
      float* row = &ym[v * channels];
      k = 0;
      for (const auto* field : fields)
        for (int c = 0; c < 3; ++c) {
          const double y = (*field)[v][c];
          row[k++] = static_cast<float>(y);
          for (int a = 0; a < kF; ++a) row[k++] = static_cast<float>(f[a] * y);
        }
    }
  });
  const Adjacency adj = WeightedAdjacency(mesh, filter);
  fm = Diffuse(mesh, adj, std::move(fm), kMoments, filter.iterations);
  ym = Diffuse(mesh, adj, std::move(ym), channels, filter.iterations);
  Features ridge;
  ridge << Eigen::Vector3d::Constant(filter.place_ridge), Eigen::Vector3d::Constant(filter.normal_ridge);
  ParallelForChunks(0, n, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      if (!usable(v)) continue;
      const double* moments = &fm[v * kMoments];
      const Features mean = Eigen::Map<const Features>(moments);
      Eigen::Matrix<double, kF, kF> cov;
      int k = kF;
      for (int a = 0; a < kF; ++a)
        for (int c = a; c < kF; ++c) cov(a, c) = cov(c, a) = moments[k++] - mean[a] * mean[c];
      cov.diagonal() += ridge;
      const Eigen::LDLT<Eigen::Matrix<double, kF, kF>> solve(cov);
      const Features offset = features(v) - mean;
      const float* row = &ym[v * channels];
      k = 0;
      for (auto* field : fields)
        for (int c = 0; c < 3; ++c, k += kPerChannel) {
          const double y = row[k];
          Features cross;
          for (int a = 0; a < kF; ++a) cross[a] = row[k + 1 + a] - mean[a] * y;
          (*field)[v][c] = static_cast<float>(y + offset.dot(solve.solve(cross)));
        }
    }
  });
}

}  // namespace lp
