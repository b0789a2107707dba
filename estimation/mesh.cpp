#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <unordered_map>

#include "common/error.h"
#include "estimation/mesh.h"

namespace lp {

void Mesh::Append(const Mesh& other) {
  const int offset = static_cast<int>(positions.size());
  const bool normals_ok = normals.size() == positions.size() && other.normals.size() == other.positions.size();
  const bool shaded_ok = shaded.size() == positions.size() && other.shaded.size() == other.positions.size();
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  albedo.insert(albedo.end(), other.albedo.begin(), other.albedo.end());
  if (shaded_ok) shaded.insert(shaded.end(), other.shaded.begin(), other.shaded.end());
  else shaded.clear();
  if (normals_ok) normals.insert(normals.end(), other.normals.begin(), other.normals.end());
  else normals.clear();
  for (const auto& t : other.triangles) triangles.push_back(t + Eigen::Vector3i::Constant(offset));
}

Mesh RefineMesh(const Mesh& mesh, int min_triangles) {
  Mesh out = mesh;
  const bool normals = out.normals.size() == out.positions.size();
  const bool albedo = out.albedo.size() == out.positions.size();
  out.shaded.clear();  // a refined mesh is for display and timing
  auto area = [&](const Eigen::Vector3i& t) {
    return (out.positions[t[1]] - out.positions[t[0]]).cross(out.positions[t[2]] - out.positions[t[0]]).norm();
  };
  std::priority_queue<std::pair<float, int>> largest;
  for (int i = 0; i < static_cast<int>(out.triangles.size()); ++i) largest.push({area(out.triangles[i]), i});
  while (static_cast<int>(out.triangles.size()) < min_triangles && !largest.empty()) {
    const int i = largest.top().second;
    largest.pop();
    const Eigen::Vector3i t = out.triangles[i];
    int e = 0;  // longest edge (t[e], t[e+1])
    float best = -1;
    for (int k = 0; k < 3; ++k) {
      const float len = (out.positions[t[(k + 1) % 3]] - out.positions[t[k]]).squaredNorm();
      if (len > best) best = len, e = k;
    }
    const int a = t[e], b = t[(e + 1) % 3], c = t[(e + 2) % 3];
    const int m = static_cast<int>(out.positions.size());
    out.positions.push_back(0.5f * (out.positions[a] + out.positions[b]));
    if (normals) out.normals.push_back((out.normals[a] + out.normals[b]).normalized());
    if (albedo) out.albedo.push_back(0.5f * (out.albedo[a] + out.albedo[b]));
    out.triangles[i] = Eigen::Vector3i(a, m, c);
    out.triangles.push_back(Eigen::Vector3i(m, b, c));
    largest.push({area(out.triangles[i]), i});
    largest.push({area(out.triangles.back()), static_cast<int>(out.triangles.size()) - 1});
  }
  return out;
}

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

void ComputeVertexNormals(Mesh* mesh) {
  mesh->normals.assign(mesh->positions.size(), Eigen::Vector3f::Zero());
  for (const auto& t : mesh->triangles) {
    const Eigen::Vector3f& a = mesh->positions[t[0]];
    const Eigen::Vector3f n = (mesh->positions[t[1]] - a).cross(mesh->positions[t[2]] - a);  // area-weighted
    if (!n.allFinite()) continue;
    for (int c = 0; c < 3; ++c) mesh->normals[t[c]] += n;
  }
  for (auto& n : mesh->normals) {
    const float len = n.norm();
    n = len > 0.f ? Eigen::Vector3f(n / len) : Eigen::Vector3f(0.f, 0.f, 0.f);
  }
}

void SmoothMesh(Mesh* mesh, int iterations, float lambda, float mu) {
  if (iterations <= 0 || mesh->triangles.empty()) return;
  const int n = static_cast<int>(mesh->positions.size());
  // Each undirected edge once, then compressed rows of neighbours.
  std::vector<std::pair<int, int>> edges;
  edges.reserve(mesh->triangles.size() * 6);
  for (const Eigen::Vector3i& t : mesh->triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      edges.emplace_back(a, b);
      edges.emplace_back(b, a);
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  std::vector<int> start(n + 1, 0), next(edges.size());
  for (const auto& e : edges) ++start[e.first + 1];
  for (int v = 0; v < n; ++v) start[v + 1] += start[v];
  for (std::size_t e = 0; e < edges.size(); ++e) next[e] = edges[e].second;
  std::vector<Eigen::Vector3f> moved(mesh->positions);
  for (int it = 0; it < iterations; ++it)
    for (const float f : {lambda, mu}) {
      for (int v = 0; v < n; ++v) {
        const int b = start[v], e = start[v + 1];
        if (b == e) continue;
        Eigen::Vector3f mean = Eigen::Vector3f::Zero();
        for (int k = b; k < e; ++k) mean += mesh->positions[next[k]];
        mean /= static_cast<float>(e - b);
        moved[v] = mesh->positions[v] + f * (mean - mesh->positions[v]);
      }
      std::swap(moved, mesh->positions);
    }
  mesh->normals.clear();
  ComputeVertexNormals(mesh);
}

int SanitizeMesh(Mesh* mesh, const std::string& name) {
  if (mesh->positions.empty()) throw InputError(name, "mesh has no vertices");
  if (mesh->triangles.empty()) throw InputError(name, "mesh has no triangles");
  if (mesh->albedo.size() != mesh->positions.size())
    mesh->albedo.assign(mesh->positions.size(), Eigen::Vector3f::Constant(0.5f));
  for (auto& a : mesh->albedo)
    for (int c = 0; c < 3; ++c) a[c] = std::isfinite(a[c]) ? std::min(std::max(a[c], 0.f), 1.f) : 0.f;
  if (!mesh->shaded.empty() && mesh->shaded.size() != mesh->positions.size()) mesh->shaded.clear();
  for (auto& a : mesh->shaded)
    for (int c = 0; c < 3; ++c) a[c] = std::isfinite(a[c]) ? std::max(a[c], 0.f) : 0.f;
  const int n = static_cast<int>(mesh->positions.size());
  std::vector<Eigen::Vector3i> kept;
  kept.reserve(mesh->triangles.size());
  for (const auto& t : mesh->triangles) {
    bool ok = true;
    for (int c = 0; c < 3; ++c) ok = ok && t[c] >= 0 && t[c] < n;
    if (!ok) throw InputError(name, "triangle index out of range");
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    const Eigen::Vector3f& a = mesh->positions[t[0]];
    const Eigen::Vector3f& b = mesh->positions[t[1]];
    const Eigen::Vector3f& c = mesh->positions[t[2]];
    if (!a.allFinite() || !b.allFinite() || !c.allFinite()) continue;
    const double area2 = (b - a).cast<double>().cross((c - a).cast<double>()).norm();
    const double scale = std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()});
    if (!(area2 > 1e-12 * scale * scale)) continue;
    kept.push_back(t);
  }
  const int removed = static_cast<int>(mesh->triangles.size() - kept.size());
  mesh->triangles.swap(kept);
  if (mesh->triangles.empty()) throw InputError(name, "mesh has no non-degenerate triangles");
  if (mesh->normals.size() != mesh->positions.size()) {
    ComputeVertexNormals(mesh);
    return removed;
  }
  // Only the unusable normals (zero, NaN: e.g. a vertex no triangle uses) are replaced by
  // the triangles' normals; the file's others are kept (they may be smoothed on purpose).
  std::vector<std::size_t> bad;
  for (std::size_t v = 0; v < mesh->normals.size(); ++v) {
    Eigen::Vector3f& nrm = mesh->normals[v];
    const float len = nrm.norm();
    if (!std::isfinite(len) || len < 1e-6f) bad.push_back(v);
    else nrm /= len;
  }
  if (!bad.empty()) {
    Mesh computed;
    computed.positions = mesh->positions;
    computed.triangles = mesh->triangles;
    ComputeVertexNormals(&computed);
    for (std::size_t v : bad) mesh->normals[v] = computed.normals[v];
  }
  return removed;
}

void MeshBounds(const Mesh& mesh, Eigen::Vector3f* lo, Eigen::Vector3f* hi) {
  *lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  *hi = Eigen::Vector3f::Constant(-std::numeric_limits<float>::max());
  for (const auto& t : mesh.triangles)
    for (int c = 0; c < 3; ++c) {
      *lo = lo->cwiseMin(mesh.positions[t[c]]);
      *hi = hi->cwiseMax(mesh.positions[t[c]]);
    }
}

Mesh UvSphere(const Eigen::Vector3f& c, float r, const Eigen::Vector3f& albedo, int rings, int segments) {
  Mesh m;
  for (int i = 0; i <= rings; ++i) {
    const double th = 3.14159265358979323846 * i / rings;
    for (int j = 0; j <= segments; ++j) {
      const double ph = 2 * 3.14159265358979323846 * j / segments;
      const Eigen::Vector3f n(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
      m.positions.push_back(c + r * n);
      m.normals.push_back(n);
      m.albedo.push_back(albedo);
    }
  }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * (segments + 1) + j, b = a + segments + 1;
      if (i > 0) m.triangles.emplace_back(a, b, a + 1);
      if (i < rings - 1) m.triangles.emplace_back(a + 1, b, b + 1);
    }
  return m;
}

}  // namespace lp
