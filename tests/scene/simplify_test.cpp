// The traced mesh (scene/simplify.h): vertex clustering with quadric placement, against
// shapes whose answer is known by hand.
#include "scene/simplify.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lp {
namespace {

/// A square of side `size` in the plane z = `z`, n x n quads of two triangles, normals +z,
/// albedo 0.2 where x < 0 and 0.8 elsewhere.
Mesh Grid(int n, double size, double z) {
  Mesh m;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const float x = static_cast<float>(size * (i / static_cast<double>(n) - 0.5));
      const float y = static_cast<float>(size * (j / static_cast<double>(n) - 0.5));
      m.positions.emplace_back(x, y, static_cast<float>(z));
      m.normals.emplace_back(0.f, 0.f, 1.f);
      m.albedo.push_back(Eigen::Vector3f::Constant(x < 0 ? 0.2f : 0.8f));
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      m.triangles.emplace_back(a, b, d);
      m.triangles.emplace_back(a, d, c);
    }
  return m;
}

/// The six faces of the axis-aligned box [lo, hi], each an n x n grid (outward normals).
Mesh Box(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, int n) {
  Mesh out;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      Mesh f;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
          Eigen::Vector3f p;
          p[axis] = side ? hi[axis] : lo[axis];
          p[u] = lo[u] + (hi[u] - lo[u]) * i / n;
          p[v] = lo[v] + (hi[v] - lo[v]) * j / n;
          f.positions.push_back(p);
          Eigen::Vector3f nrm = Eigen::Vector3f::Zero();
          nrm[axis] = side ? 1.f : -1.f;
          f.normals.push_back(nrm);
          f.albedo.push_back(Eigen::Vector3f::Constant(0.5f));
        }
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
          if (side) {
            f.triangles.emplace_back(a, b, d);
            f.triangles.emplace_back(a, d, c);
          } else {
            f.triangles.emplace_back(a, d, b);
            f.triangles.emplace_back(a, c, d);
          }
        }
      out.Append(f);
    }
  return out;
}

TEST(MeshArea, AUnitSquareOfManyTriangles) { EXPECT_NEAR(MeshArea(Grid(37, 1.0, 0.2)), 1.0, 1e-9); }

TEST(ClusterVertices, AFlatSquareStaysInItsPlaneWithItsArea) {
  // A plane lying exactly on a cell boundary (z = 0) and one between boundaries.
  for (double z : {0.0, 0.0137}) {
    const Mesh fine = Grid(100, 1.0, z);
    const ClusteredMesh c = ClusterVertices(fine, 0.05f);
    EXPECT_LT(c.mesh.triangles.size() * 10, fine.triangles.size()) << "z " << z;
    for (const Eigen::Vector3f& p : c.mesh.positions) ASSERT_NEAR(p.z(), z, 1e-6) << "z " << z;
    // The clusters of the border pull it in by at most half a cell on each side.
    EXPECT_GT(MeshArea(c.mesh), (1.0 - 0.05) * (1.0 - 0.05)) << "z " << z;
    EXPECT_LE(MeshArea(c.mesh), 1.0 + 1e-4) << "z " << z;
    for (const Eigen::Vector3f& n : c.mesh.normals) EXPECT_NEAR(n.z(), 1.f, 1e-6f);
  }
}

TEST(ClusterVertices, CornersStayWhereTheyWere) {
  // Corners off the grid: the cluster's mean would round them off by up to half a cell;
  // the planes' least-squares point keeps them.
  const Eigen::Vector3f lo(0.013f, -0.021f, 0.007f), hi(0.513f, 0.379f, 0.307f);
  const Mesh fine = Box(lo, hi, 40);
  const ClusteredMesh c = ClusterVertices(fine, 0.06f);
  EXPECT_LT(c.mesh.triangles.size() * 4, fine.triangles.size());
  Eigen::Vector3f clo, chi;
  MeshBounds(c.mesh, &clo, &chi);
  EXPECT_LT((clo - lo).cwiseAbs().maxCoeff(), 1e-5f) << clo.transpose();
  EXPECT_LT((chi - hi).cwiseAbs().maxCoeff(), 1e-5f) << chi.transpose();
  // Every vertex still on the box's surface: one coordinate on a face, the others inside.
  for (const Eigen::Vector3f& p : c.mesh.positions) {
    const float to_face = std::min((p - lo).cwiseAbs().minCoeff(), (p - hi).cwiseAbs().minCoeff());
    EXPECT_LT(to_face, 1e-5f) << p.transpose();
  }
  EXPECT_NEAR(MeshArea(c.mesh), MeshArea(fine), 1e-3 * MeshArea(fine));
}

TEST(ClusterVertices, EachVertexMapsToItsCellsVertexAndAttributesAverage) {
  const Mesh fine = Grid(40, 1.0, 0.3);
  const float cell = 0.1f;
  const ClusteredMesh c = ClusterVertices(fine, cell);
  ASSERT_EQ(c.cluster.size(), fine.positions.size());
  for (std::size_t v = 0; v < fine.positions.size(); ++v) {
    ASSERT_GE(c.cluster[v], 0);
    const Eigen::Vector3f d = c.mesh.positions[c.cluster[v]] - fine.positions[v];
    EXPECT_LE(d.cwiseAbs().maxCoeff(), 1.5f * cell);
  }
  // Albedo is the members' mean: 0.2 left of x = 0, 0.8 right (x = 0 is a cell boundary).
  for (std::size_t k = 0; k < c.mesh.positions.size(); ++k) {
    const float a = c.mesh.albedo[k].x();
    if (c.mesh.positions[k].x() < -0.01f) {
      EXPECT_NEAR(a, 0.2f, 1e-6f);
    }
    if (c.mesh.positions[k].x() > 0.01f) {
      EXPECT_NEAR(a, 0.8f, 1e-6f);
    }
  }
}

TEST(ClusterVertices, ACellLargerThanTheMeshLeavesNothingAndSaysSo) {
  Mesh small = Grid(4, 0.1, 0.05);
  for (Eigen::Vector3f& p : small.positions) p += Eigen::Vector3f::Constant(1.f);  // all in cell (0, 0, 0)
  EXPECT_THROW(ClusterVertices(small, 10.f), InputError);
}

TEST(PixelFootprints, DepthOverFocalLengthInTheNearestViewAndInfinityOutside) {
  Mesh m;
  m.positions = {{0, 0, 2}, {0, 0, 4}, {0, 0, -3}, {10, 0, 2}};
  Camera near, far;
  near.width = far.width = 160;
  near.height = far.height = 120;
  near.fx = near.fy = 100;
  far.fx = far.fy = 400;  // a longer lens: its pixels span less
  near.cx = far.cx = 79.5;
  near.cy = far.cy = 59.5;
  far.world_from_camera(2, 3) = -2;  // 2 m further back
  const std::vector<float> f = PixelFootprints(m, {near, far});
  EXPECT_FLOAT_EQ(f[0], 4.f / 400);   // far view: depth 4, focal 400 (near: 2/100)
  EXPECT_FLOAT_EQ(f[1], 6.f / 400);   // far: 6/400 = 0.015 < near: 4/100
  EXPECT_TRUE(std::isinf(f[2]));      // behind both
  EXPECT_TRUE(std::isinf(f[3]));      // outside both images
  EXPECT_FLOAT_EQ(FiniteQuantile(f, 0.0), 4.f / 400);
  EXPECT_FLOAT_EQ(FiniteQuantile({std::numeric_limits<float>::infinity()}, 0.5), 0.f);
}

}  // namespace
}  // namespace lp
