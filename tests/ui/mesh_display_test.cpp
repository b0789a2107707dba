// The viewer's coarse mesh for drawing while the view moves.
#include <gtest/gtest.h>

#include "tests/test_util.h"
#include "ui/mesh_display.h"

namespace lp {
namespace {

Mesh ComputeNormalsOf(Mesh m) {
  ComputeVertexNormals(&m);
  return m;
}

TEST(SimplifyForDisplay, FitsTheBudgetKeepsTheSurfaceAndCarriesValues) {
  const Mesh fine = ComputeNormalsOf(RefineMesh(test::Ball(1.0, 0.5, 64, 128), 200000));
  std::vector<int> cluster_of;
  const Mesh coarse = SimplifyForDisplay(fine, 60000, &cluster_of);
  EXPECT_LE(coarse.triangles.size(), 60000u);
  EXPECT_GT(coarse.triangles.size(), 10000u) << "not coarser than needed";
  ASSERT_EQ(cluster_of.size(), fine.positions.size());
  for (const auto& p : coarse.positions) EXPECT_NEAR(p.norm(), 1.0, 0.02) << "on the sphere";
  for (std::size_t v = 0; v < coarse.positions.size(); ++v)
    EXPECT_GT(coarse.normals[v].dot(coarse.positions[v].normalized()), 0.9f) << "outward normals";
  const std::vector<Eigen::Vector3f> ones(fine.positions.size(), Eigen::Vector3f(0.25f, 0.5f, 1.f));
  for (const auto& c : AverageOverClusters(ones, cluster_of, static_cast<int>(coarse.positions.size())))
    EXPECT_TRUE(c.isApprox(Eigen::Vector3f(0.25f, 0.5f, 1.f)));
  // Small meshes are shown as they are.
  const Mesh small = test::Plane(1.0, 0.5);
  EXPECT_EQ(SimplifyForDisplay(small, 60000, &cluster_of).triangles.size(), 2u);
  EXPECT_EQ(cluster_of, (std::vector<int>{0, 1, 2, 3}));
}

}  // namespace
}  // namespace lp
