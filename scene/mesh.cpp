#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <unordered_map>

#include "common/error.h"
#include "common/parallel.h"
#include "scene/mesh.h"

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
  const bool label_ok = label.size() + other.label.size() == positions.size();  // (positions already appended)
  const bool emission_ok = emission.size() + other.emission.size() == positions.size();
  if (label_ok) label.insert(label.end(), other.label.begin(), other.label.end());
  else label.clear();
  if (emission_ok) emission.insert(emission.end(), other.emission.begin(), other.emission.end());
  else emission.clear();
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
  const std::size_t n = mesh->positions.size();
  // Each vertex's neighbours (the other corners of its triangles), each once: rows
  // [start[v], end[v]) of `next`.
  std::vector<std::size_t> start(n + 1, 0);
  for (const Eigen::Vector3i& t : mesh->triangles)
    for (int k = 0; k < 3; ++k) start[t[k] + 1] += 2;
  for (std::size_t v = 0; v < n; ++v) start[v + 1] += start[v];
  std::vector<int> next(start[n]);
  std::vector<std::size_t> end(start.begin(), start.end() - 1);
  for (const Eigen::Vector3i& t : mesh->triangles)
    for (int k = 0; k < 3; ++k) {
      next[end[t[k]]++] = t[(k + 1) % 3];
      next[end[t[k]]++] = t[(k + 2) % 3];
    }
  ParallelForChunks(0, n, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      std::sort(next.begin() + start[v], next.begin() + end[v]);
      end[v] = std::unique(next.begin() + start[v], next.begin() + end[v]) - next.begin();
    }
  });
  std::vector<Eigen::Vector3f> moved(mesh->positions);
  for (int it = 0; it < iterations; ++it)
    for (const float f : {lambda, mu}) {
      ParallelForChunks(0, n, 4096, [&](std::size_t b, std::size_t e) {
        for (std::size_t v = b; v < e; ++v) {
          if (start[v] == end[v]) continue;
          Eigen::Vector3f mean = Eigen::Vector3f::Zero();
          for (std::size_t k = start[v]; k < end[v]; ++k) mean += mesh->positions[next[k]];
          mean /= static_cast<float>(end[v] - start[v]);
          moved[v] = mesh->positions[v] + f * (mean - mesh->positions[v]);
        }
      });
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

Mesh WithoutTriangles(const Mesh& mesh, const std::vector<std::uint8_t>& drop) {
  Mesh out = mesh;
  out.triangles.clear();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    if (t >= drop.size() || !drop[t]) out.triangles.push_back(mesh.triangles[t]);
  return out;
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

void BoundingSphere(const Mesh& mesh, Eigen::Vector3d* centre, double* radius) {
  Eigen::Vector3f lo, hi;
  MeshBounds(mesh, &lo, &hi);
  *centre = (0.5f * (lo + hi)).cast<double>();
  *radius = std::max(1e-9, 0.5 * (hi - lo).cast<double>().norm());
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
