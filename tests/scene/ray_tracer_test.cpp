// RayTracer with openings: triangles left out of the BVH let rays through, and every other
// triangle keeps its index (the emitters', clusters' and segments' triangle ids).
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "scene/ray_tracer.h"
#include "tests/test_util.h"

namespace lp {
namespace {

using test::Merge;
using test::Plane;

/// Two 4 m planes, z = 0 (triangles 0-1) and z = 1 (2-3), albedo 0.7 and 0.3.
Mesh TwoPlanes() {
  Mesh upper = Plane(4, 0.3);
  for (Eigen::Vector3f& p : upper.positions) p.z() += 1;
  return Merge(Plane(4, 0.7), upper);
}

TEST(RayTracer, OpenTrianglesLetRaysThroughAndTheOthersKeepTheirIndices) {
  const Mesh mesh = TwoPlanes();
  ASSERT_EQ(mesh.triangles.size(), 4u);
  const RayTracer closed(mesh), opened(mesh, {0, 0, 1, 1});
  const Eigen::Vector3d from(0.3, -0.2, 2), down(0, 0, -1);
  SurfacePoint a, b;
  ASSERT_TRUE(closed.Intersect(from, down, &a));
  ASSERT_TRUE(opened.Intersect(from, down, &b));
  EXPECT_NEAR(a.position.z(), 1, 1e-6);  // the upper plane
  EXPECT_GE(a.triangle, 2);
  EXPECT_NEAR(b.position.z(), 0, 1e-6);  // through it, the lower plane: its own index and albedo
  EXPECT_LE(b.triangle, 1);
  EXPECT_NEAR(b.albedo.x(), 0.7, 1e-6);
  // Shadow rays (one by one and as a stream) pass the opening too.
  const Eigen::Vector3d above_floor(0.3, -0.2, 0.5), up(0, 0, 1);
  EXPECT_TRUE(closed.Occluded(above_floor, up));
  EXPECT_FALSE(opened.Occluded(above_floor, up));
  std::vector<std::uint8_t> blocked;
  opened.OccludedMany({{above_floor.cast<float>(), up.cast<float>(), 10.f}}, &blocked);
  EXPECT_EQ(blocked, std::vector<std::uint8_t>{0});
  EXPECT_EQ(opened.open(), (std::vector<std::uint8_t>{0, 0, 1, 1}));
  EXPECT_TRUE(closed.open().empty());
  EXPECT_EQ(opened.mesh().triangles.size(), 4u);
  // Opening the lower plane instead: the upper one is hit as before, with its index.
  const RayTracer lower_open(mesh, {1, 1, 0, 0});
  SurfacePoint c;
  ASSERT_TRUE(lower_open.Intersect(from, down, &c));
  EXPECT_EQ(c.triangle, a.triangle);
  EXPECT_FALSE(lower_open.Intersect(Eigen::Vector3d(0.3, -0.2, 0.5), down, &c));
}

}  // namespace
}  // namespace lp
