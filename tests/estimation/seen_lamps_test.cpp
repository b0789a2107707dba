// Lamps the cameras saw (issue 43): clipped blobs placed by the mesh's depth or by
// triangulation across views, against the places the blobs were drawn from.
#include <gtest/gtest.h>

#include "estimation/seen_lamps.h"
#include "tests/test_util.h"

namespace lp {
namespace {

using test::BlankView;
using test::LookAt;

/// A 4 m floor (z = 0) and two views of it from either side, 160 x 120.
struct FloorAndTwoViews {
  RayTracer scene{test::Plane(4, 0.7)};
  std::vector<View> views{BlankView(LookAt({1.5, -1.5, 1.5}, {0, 0, 0.3}, 160, 120, 60)),
                          BlankView(LookAt({-1.5, -1.6, 1.4}, {0, 0, 0.3}, 160, 120, 60))};

  /// Marks off the mesh the pixels of view k whose centre's ray passes within `radius` of
  /// `bulb` (a sphere the depth camera returned nothing for); the count marked.
  int SeeBulb(std::size_t k, const Eigen::Vector3d& bulb, double radius) {
    View& v = views[k];
    v.clipped_off.assign(v.valid.size(), 0);
    int n = 0;
    for (std::size_t p = 0; p < v.valid.size(); ++p) {
      const Camera& c = v.camera;
      const Eigen::Vector3d d = c.RayDirection(static_cast<double>(p % c.width), static_cast<double>(p / c.width));
      const Eigen::Vector3d to = bulb - c.center();
      if ((to - to.dot(d) * d).norm() < radius && to.dot(d) > 0) v.clipped_off[p] = 1, v.valid[p] = 0, ++n;
    }
    return n;
  }
};

TEST(SeenLamps, ABulbWithNoDepthIsTriangulatedWhereItIs) {
  FloorAndTwoViews s;
  const Eigen::Vector3d bulb(0.3, -0.2, 0.8);
  ASSERT_GT(s.SeeBulb(0, bulb, 0.03), 4);
  ASSERT_GT(s.SeeBulb(1, bulb, 0.03), 4);
  const std::vector<SeenLamp> seen = SeenLamps(s.views, s.scene);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].how, "triangulated");
  EXPECT_EQ(seen[0].views, 2);
  // The blobs' mean pixels, each within a pixel (1.7 cm at 2.4 m) of the bulb's projection.
  EXPECT_LT((seen[0].position - bulb).norm(), 0.01) << seen[0].position.transpose();
  EXPECT_LT(seen[0].gap, 0.01);
}

TEST(SeenLamps, ATriangulatedPlacesCovarianceIsTheRaysClosedForm) {
  // Two views 1 m apart, 2 m before a bulb at their images' centres: rays at +-phi about the
  // bisector (y), each kSeenPixelSigma pixels off (sigma = that times the distance over the
  // focal length). Their least-squares meeting point's variance is sigma^2 / (2 sin^2 phi)
  // along the bisector, sigma^2 / (2 cos^2 phi) across it in their plane (x) and sigma^2 / 2
  // out of it (z); the gap (none here) adds to every axis.
  const RayTracer scene{test::Plane(4, 0.7)};
  const Eigen::Vector3d bulb(0, 0, 0.8);
  std::vector<View> views{BlankView(LookAt({0.5, -2, 0.8}, bulb, 161, 121, 60)),
                          BlankView(LookAt({-0.5, -2, 0.8}, bulb, 161, 121, 60))};
  for (View& v : views) {  // the bulb's blob: a 3 x 3 square about the centre pixel (80, 60)
    v.clipped_off.assign(v.valid.size(), 0);
    for (int y = 59; y <= 61; ++y)
      for (int x = 79; x <= 81; ++x) v.clipped_off[static_cast<std::size_t>(y) * 161 + x] = 1;
  }
  const std::vector<SeenLamp> seen = SeenLamps(views, scene);
  ASSERT_EQ(seen.size(), 1u);
  ASSERT_LT((seen[0].position - bulb).norm(), 1e-6) << seen[0].position.transpose();
  const double distance = std::sqrt(0.25 + 4), phi = std::atan2(0.5, 2);
  const double sigma = kSeenPixelSigma * distance / views[0].camera.fx;
  const Eigen::Matrix3d& c = seen[0].covariance;
  EXPECT_NEAR(c(1, 1), sigma * sigma / (2 * std::sin(phi) * std::sin(phi)), 1e-3 * c(1, 1));
  EXPECT_NEAR(c(0, 0), sigma * sigma / (2 * std::cos(phi) * std::cos(phi)), 1e-3 * c(0, 0));
  EXPECT_NEAR(c(2, 2), sigma * sigma / 2, 1e-3 * c(2, 2));
  EXPECT_NEAR(c(0, 1), 0, 1e-9);
  EXPECT_NEAR(c(1, 2), 0, 1e-9);
}

TEST(SeenLamps, ABlobOnTheMeshIsPlacedJustBeforeItsSurface) {
  FloorAndTwoViews s;
  const Eigen::Vector3d spot(-0.4, 0.3, 0);  // a glowing patch of floor (clipped, depth seen)
  View& v = s.views[0];
  v.clipped.assign(v.valid.size(), 0);
  const Camera& c = v.camera;
  for (std::size_t p = 0; p < v.valid.size(); ++p) {
    SurfacePoint hit;
    const Eigen::Vector3d d = c.RayDirection(static_cast<double>(p % c.width), static_cast<double>(p / c.width));
    if (s.scene.Intersect(c.center(), d, &hit) && (hit.position - spot).norm() < 0.06) v.clipped[p] = 1;
  }
  const std::vector<SeenLamp> seen = SeenLamps(s.views, s.scene);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].how, "depth");
  // 2 cm from the floor towards the camera along the mean pixel's ray.
  const Eigen::Vector3d to_camera = (c.center() - seen[0].position).normalized();
  const Eigen::Vector3d on_floor = seen[0].position - 0.02 * to_camera;
  EXPECT_NEAR(on_floor.z(), 0, 1e-6);
  EXPECT_LT((on_floor - spot).norm(), 0.01);
  EXPECT_GT(seen[0].position.z(), 0.005);
}

TEST(SeenLamps, WhatOneViewAloneSeesOffTheMeshPlacesNothing) {
  FloorAndTwoViews s;
  ASSERT_GT(s.SeeBulb(0, {0.3, -0.2, 0.8}, 0.03), 4);
  EXPECT_TRUE(SeenLamps(s.views, s.scene).empty());
}

TEST(SeenLamps, RaysFromOnePlaceDoNotTriangulate) {
  FloorAndTwoViews s;
  s.views[1] = s.views[0];  // the camera did not move: the rays are parallel
  ASSERT_GT(s.SeeBulb(0, {0.3, -0.2, 0.8}, 0.03), 4);
  ASSERT_GT(s.SeeBulb(1, {0.3, -0.2, 0.8}, 0.03), 4);
  EXPECT_TRUE(SeenLamps(s.views, s.scene).empty());
}

TEST(SeenLamps, RaysMeetingBehindTheSurfaceTheySeePlaceNothing) {
  FloorAndTwoViews s;
  const Eigen::Vector3d below(0.2, 0.1, -0.6);  // under the floor: each ray hits the floor first
  ASSERT_GT(s.SeeBulb(0, below, 0.03), 2);
  ASSERT_GT(s.SeeBulb(1, below, 0.03), 2);
  EXPECT_TRUE(SeenLamps(s.views, s.scene).empty());
}

TEST(SeenLamps, BlobsThatMissEachOtherOrFillTheViewPlaceNothing) {
  FloorAndTwoViews s;
  ASSERT_GT(s.SeeBulb(0, {0.3, -0.2, 0.8}, 0.03), 4);
  ASSERT_GT(s.SeeBulb(1, {-0.3, 0.4, 0.8}, 0.03), 4);  // another place: the rays pass 0.7 m apart
  EXPECT_TRUE(SeenLamps(s.views, s.scene).empty());
  // A tenth of the view or more is not a lamp (a window, a white wall over-exposed).
  ASSERT_GT(s.SeeBulb(0, {0.3, -0.2, 0.8}, 0.4), 1920);
  ASSERT_GT(s.SeeBulb(1, {0.3, -0.2, 0.8}, 0.4), 1920);
  EXPECT_TRUE(SeenLamps(s.views, s.scene).empty());
}

TEST(SeenLamps, BlobsAreEightConnected) {
  View v = BlankView(LookAt({0, 0, 1}, {0, 0, 0}, 8, 6, 60));
  v.clipped.assign(48, 0);
  v.clipped_off.assign(48, 0);
  // A diagonal pair (one blob of two, one on and one off the mesh) and a lone pixel.
  v.clipped[1 * 8 + 1] = 1;
  v.clipped_off[2 * 8 + 2] = 1;
  v.clipped[4 * 8 + 6] = 1;
  const std::vector<ClippedBlob> blobs = ClippedBlobs({v});
  ASSERT_EQ(blobs.size(), 2u);
  EXPECT_EQ(blobs[0].pixels, 2);
  EXPECT_EQ(blobs[0].off_mesh, 1);
  EXPECT_DOUBLE_EQ(blobs[0].u, 1.5);
  EXPECT_DOUBLE_EQ(blobs[0].v, 1.5);
  EXPECT_EQ(blobs[1].pixels, 1);
  EXPECT_DOUBLE_EQ(blobs[1].u, 6);
  EXPECT_DOUBLE_EQ(blobs[1].v, 4);
}

}  // namespace
}  // namespace lp
