#include "scene/simplify.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include <Eigen/Eigenvalues>

#include "common/error.h"

namespace lp {
namespace {

/// The sum of squared distances to planes, weighted by area: x^T M x + 2 b^T x + c.
struct Quadric {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  void AddPlane(const Eigen::Vector3d& n, double d, double weight) {
    m += weight * n * n.transpose();
    b += weight * d * n;
  }
  /// The least point, searched only along the directions the planes pin down (singular
  /// values at least 1 % of the largest); the others keep `mean`'s coordinate.
  Eigen::Vector3d Minimizer(const Eigen::Vector3d& mean) const {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m);
    const Eigen::Vector3d lam = eig.eigenvalues();
    const double top = lam.maxCoeff();
    if (!(top > 0) || !std::isfinite(top)) return mean;
    const Eigen::Vector3d residual = -b - m * mean;  // the gradient's negative at the mean, over 2
    Eigen::Vector3d x = mean;
    for (int i = 0; i < 3; ++i)
      if (lam[i] > 1e-2 * top) {
        const Eigen::Vector3d u = eig.eigenvectors().col(i);
        x += u * (u.dot(residual) / lam[i]);
      }
    return x;
  }
};

struct Cluster {
  Eigen::Vector3i cell;
  Eigen::Vector3d sum_position = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_albedo = Eigen::Vector3d::Zero(), sum_shaded = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_normal = Eigen::Vector3d::Zero();
  int count = 0;
  Quadric quadric;
};

std::uint64_t CellKey(const Eigen::Vector3i& c) {
  const auto bits = [](int v) { return static_cast<std::uint64_t>(static_cast<std::uint32_t>(v) & 0x1fffff); };
  return bits(c.x()) | bits(c.y()) << 21 | bits(c.z()) << 42;
}

/// The triangles of `triangles` whose vertices fall in three clusters (`cluster`: per
/// vertex), as triangles of clusters, each once (the first one's winding).
std::vector<Eigen::Vector3i> ClusteredTriangles(const std::vector<Eigen::Vector3i>& triangles,
                                                const std::vector<int>& cluster) {
  std::vector<std::pair<std::array<int, 3>, Eigen::Vector3i>> tris;
  tris.reserve(triangles.size() / 2);
  for (const Eigen::Vector3i& t : triangles) {
    const Eigen::Vector3i c(cluster[t[0]], cluster[t[1]], cluster[t[2]]);
    if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;
    std::array<int, 3> key{c[0], c[1], c[2]};
    std::sort(key.begin(), key.end());
    tris.emplace_back(key, c);
  }
  std::stable_sort(tris.begin(), tris.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Eigen::Vector3i> out;
  for (std::size_t i = 0; i < tris.size(); ++i)
    if (i == 0 || tris[i].first != tris[i - 1].first) out.push_back(tris[i].second);
  return out;
}

}  // namespace

ClusteredMesh ClusterVertices(const Mesh& mesh, float cell) {
  LP_CHECK(cell > 0 && std::isfinite(cell), "cluster grid must be positive");
  const std::size_t n = mesh.positions.size();
  const bool has_shaded = mesh.shaded.size() == n, has_normals = mesh.normals.size() == n,
             has_albedo = mesh.albedo.size() == n;
  std::vector<char> used(n, 0);
  for (const Eigen::Vector3i& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) used[t[k]] = 1;

  ClusteredMesh out;
  out.cluster.assign(n, -1);
  std::vector<Cluster> clusters;
  std::unordered_map<std::uint64_t, int> index;
  index.reserve(n / 4 + 16);
  for (std::size_t v = 0; v < n; ++v) {
    if (!used[v]) continue;
    const Eigen::Vector3f& p = mesh.positions[v];
    const Eigen::Vector3i c = (p.cast<double>() / cell).array().floor().max(-1e9).min(1e9).cast<int>();
    auto [it, fresh] = index.emplace(CellKey(c), static_cast<int>(clusters.size()));
    if (fresh) {
      clusters.emplace_back();
      clusters.back().cell = c;
    }
    Cluster& k = clusters[it->second];
    out.cluster[v] = it->second;
    k.sum_position += p.cast<double>();
    if (has_albedo) k.sum_albedo += mesh.albedo[v].cast<double>();
    if (has_shaded) k.sum_shaded += mesh.shaded[v].cast<double>();
    if (has_normals) k.sum_normal += mesh.normals[v].cast<double>();
    ++k.count;
  }
  // Each triangle's plane, weighted by its area, in the quadric of every cluster it touches.
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
    const Eigen::Vector3d cr = (mesh.positions[t[1]].cast<double>() - a).cross(mesh.positions[t[2]].cast<double>() - a);
    const double twice_area = cr.norm();
    if (!(twice_area > 0) || !std::isfinite(twice_area)) continue;
    const Eigen::Vector3d normal = cr / twice_area;
    const int c0 = out.cluster[t[0]], c1 = out.cluster[t[1]], c2 = out.cluster[t[2]];
    clusters[c0].quadric.AddPlane(normal, -normal.dot(a), twice_area / 2);
    if (c1 != c0) clusters[c1].quadric.AddPlane(normal, -normal.dot(a), twice_area / 2);
    if (c2 != c0 && c2 != c1) clusters[c2].quadric.AddPlane(normal, -normal.dot(a), twice_area / 2);
  }

  Mesh& m = out.mesh;
  const std::size_t k = clusters.size();
  m.positions.resize(k);
  m.albedo.resize(k);
  if (has_shaded) m.shaded.resize(k);
  if (has_normals) m.normals.resize(k);
  for (std::size_t i = 0; i < k; ++i) {
    const Cluster& c = clusters[i];
    const Eigen::Vector3d mean = c.sum_position / c.count;
    Eigen::Vector3d x = c.quadric.Minimizer(mean);
    const Eigen::Array3d lo = (c.cell.cast<double>().array() - 0.5) * cell, hi = lo + 2.0 * cell;
    if (!x.allFinite() || (x.array() < lo).any() || (x.array() > hi).any()) x = mean;
    m.positions[i] = x.cast<float>();
    m.albedo[i] = has_albedo ? Eigen::Vector3f((c.sum_albedo / c.count).cast<float>()) : Eigen::Vector3f::Constant(0.5f);
    if (has_shaded) m.shaded[i] = (c.sum_shaded / c.count).cast<float>();
    if (has_normals) {
      const double len = c.sum_normal.norm();
      m.normals[i] = len > 0 ? Eigen::Vector3f((c.sum_normal / len).cast<float>()) : Eigen::Vector3f::Zero();
    }
  }

  m.triangles = ClusteredTriangles(mesh.triangles, out.cluster);
  if (m.triangles.empty())
    throw InputError("a grid of " + std::to_string(cell) + " m leaves the mesh no triangle");
  return out;
}

std::vector<float> PixelFootprints(const Mesh& mesh, const std::vector<Camera>& cameras) {
  std::vector<float> out(mesh.positions.size(), std::numeric_limits<float>::infinity());
  for (const Camera& cam : cameras) {
    const Eigen::Matrix3d camera_from_world = cam.world_from_camera.block<3, 3>(0, 0).transpose();
    const Eigen::Vector3d centre = cam.center();
    const double focal = std::max(cam.fx, cam.fy);
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      const Eigen::Vector3d p = camera_from_world * (mesh.positions[v].cast<double>() - centre);
      if (p.z() <= 1e-9) continue;
      const double u = cam.fx * p.x() / p.z() + cam.cx, w = cam.fy * p.y() / p.z() + cam.cy;
      if (u < -0.5 || w < -0.5 || u > cam.width - 0.5 || w > cam.height - 0.5) continue;
      out[v] = std::min(out[v], static_cast<float>(p.z() / focal));
    }
  }
  return out;
}

float FiniteQuantile(std::vector<float> v, double q) {
  v.erase(std::remove_if(v.begin(), v.end(), [](float x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return 0;
  const std::size_t i = std::min(v.size() - 1, static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * v.size()));
  std::nth_element(v.begin(), v.begin() + i, v.end());
  return v[i];
}

float MedianEdgeLength(const Mesh& mesh) {
  std::vector<float> len;
  len.reserve(mesh.triangles.size() * 3);
  for (const Eigen::Vector3i& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) len.push_back((mesh.positions[t[k]] - mesh.positions[t[(k + 1) % 3]]).norm());
  return FiniteQuantile(std::move(len), 0.5);
}

double MeshArea(const Mesh& mesh) {
  double area = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
    area += 0.5 * (mesh.positions[t[1]].cast<double>() - a).cross(mesh.positions[t[2]].cast<double>() - a).norm();
  }
  return area;
}

}  // namespace lp
