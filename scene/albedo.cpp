#include "scene/albedo.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "common/error.h"

namespace lp {

namespace {

struct Segments {
  std::vector<int> parent;
  std::vector<Eigen::Vector3d> sum;  // colour sums
  std::vector<int> count;

  int Find(int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  Eigen::Vector3d Mean(int root) const { return sum[root] / count[root]; }
};

Eigen::Vector3d Chroma(const Eigen::Vector3d& c) {
  const double s = c.sum();
  return s > 1e-6 ? Eigen::Vector3d(c / s) : Eigen::Vector3d::Constant(1.0 / 3);
}

}  // namespace

int FlattenAlbedo(Mesh* mesh, const AlbedoOptions& o) {
  if (!o.segment || mesh->albedo.size() != mesh->positions.size()) return 0;
  const int n = static_cast<int>(mesh->positions.size());
  struct Edge {
    float cost;
    int a, b;
  };
  std::vector<Edge> edges;
  edges.reserve(mesh->triangles.size() * 3 / 2 + 1);
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(mesh->triangles.size() * 3);
  for (const Eigen::Vector3i& t : mesh->triangles)
    for (int k = 0; k < 3; ++k) pairs.emplace_back(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
  std::sort(pairs.begin(), pairs.end());  // each edge once, boundary edges included
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  for (const auto& [a, b] : pairs) {
      const Eigen::Vector3d ca = mesh->albedo[a].cast<double>(), cb = mesh->albedo[b].cast<double>();
      const double chroma = (Chroma(ca) - Chroma(cb)).norm();
      const double log_step = std::abs(std::log(std::max(1e-4, ca.sum())) - std::log(std::max(1e-4, cb.sum())));
      if (chroma < o.max_chroma_step && log_step < o.max_log_step)
        edges.push_back({static_cast<float>(chroma / o.max_chroma_step + log_step / o.max_log_step), a, b});
    }
  // The smoothest joins first (Felzenszwalb-style), each checked against the segments' means.
  std::sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) { return x.cost < y.cost; });
  Segments s;
  s.parent.resize(n);
  std::iota(s.parent.begin(), s.parent.end(), 0);
  s.count.assign(n, 1);
  s.sum.resize(n);
  for (int v = 0; v < n; ++v) s.sum[v] = mesh->albedo[v].cast<double>();
  for (const Edge& e : edges) {
    const int ra = s.Find(e.a), rb = s.Find(e.b);
    if (ra == rb) continue;
    if ((Chroma(s.Mean(ra)) - Chroma(s.Mean(rb))).norm() > o.max_chroma_spread) continue;
    if (std::abs(std::log(std::max(1e-4, s.Mean(ra).sum())) - std::log(std::max(1e-4, s.Mean(rb).sum()))) >
        o.max_log_spread)
      continue;
    const int big = s.count[ra] >= s.count[rb] ? ra : rb, small = big == ra ? rb : ra;
    s.parent[small] = big;
    s.sum[big] += s.sum[small];
    s.count[big] += s.count[small];
  }
  int flattened = 0;
  std::vector<char> counted(n, 0);
  for (int v = 0; v < n; ++v) {
    const int r = s.Find(v);
    if (s.count[r] < o.min_segment) continue;
    mesh->albedo[v] = s.Mean(r).cast<float>();
    if (!counted[r]) counted[r] = 1, ++flattened;
  }
  return flattened;
}

AlbedoOptions DelitAlbedoOptions() {
  AlbedoOptions o;
  o.max_log_spread = o.max_log_step;
  return o;
}

int DelightAlbedo(Mesh* mesh, const std::vector<float>& irradiance, const AlbedoOptions& options, double scale) {
  const std::size_t n = mesh->positions.size();
  LP_CHECK(mesh->shaded.size() == n && irradiance.size() == n && mesh->albedo.size() == n,
           "DelightAlbedo: shaded colours and irradiance per vertex");
  std::vector<float> sorted;
  sorted.reserve(n);
  for (float e : irradiance)
    if (std::isfinite(e) && e > 0) sorted.push_back(e);
  if (sorted.empty()) return -1;  // nothing lit: nothing to divide by
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const float floor = 0.05f * sorted[sorted.size() / 2];
  double before = 0, after = 0;  // the scale of the colours seen, whatever earlier passes did
  for (const Eigen::Vector3f& c : mesh->shaded) before += c.sum();
  if (!(before > 0) || !std::isfinite(before)) return -1;  // nothing seen (black colours)
  for (std::size_t v = 0; v < n; ++v) {
    const float e = std::isfinite(irradiance[v]) ? std::max(floor, irradiance[v]) : floor;
    mesh->albedo[v] = mesh->shaded[v] / e;  // grey: the colour seen keeps its chromaticity
  }
  const int segments = FlattenAlbedo(mesh, options);  // keeps each segment's sum: after > 0
  for (const Eigen::Vector3f& a : mesh->albedo) after += a.sum();
  // The scale stays the reconstruction's (the mean colour seen, which flattening keeps): it
  // sets the interreflections.
  // The de-lit colours have a long tail (demo: 90th percentile 0.37, 99th 2.4 at this
  // scale), which is clipped at 0.95; scaling everything down to fit the tail instead
  // fitted the demo worse (docs/method.md).
  ScaleAlbedo(mesh, scale * before / after);
  return segments;
}

double AlbedoScaleTo(const Mesh& mesh, double median) {
  if (!(median > 0) || mesh.albedo.empty()) return 1;
  std::vector<float> lum;
  lum.reserve(mesh.albedo.size());
  for (const Eigen::Vector3f& a : mesh.albedo) lum.push_back(0.2126f * a.x() + 0.7152f * a.y() + 0.0722f * a.z());
  const std::size_t k = lum.size() / 2;
  std::nth_element(lum.begin(), lum.begin() + k, lum.end());
  return lum[k] > 0 && std::isfinite(lum[k]) ? median / lum[k] : 1;
}

void ScaleAlbedo(Mesh* mesh, double scale) {
  const float s = static_cast<float>(scale);
  for (Eigen::Vector3f& a : mesh->albedo) a = (a * s).cwiseMax(0.f).cwiseMin(kMaxAlbedo);
}

}  // namespace lp
