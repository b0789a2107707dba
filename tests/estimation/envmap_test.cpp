#include "estimation/envmap.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/rng.h"
#include "estimation/truth.h"

namespace lp {
namespace {

TEST(EnvMap, TwentyOneRingsGive522Directions) {
  EXPECT_EQ(EnvMap(21, Eigen::Vector3d::UnitZ()).size(), 522);
}

class EnvMapRings : public ::testing::TestWithParam<int> {};

TEST_P(EnvMapRings, SolidAnglesSumTo4PiAndLookupIsConsistent) {
  const EnvMap env(GetParam(), Eigen::Vector3d(0.3, -1, 0.2));
  double sum = 0;
  for (int j = 0; j < env.size(); ++j) {
    EXPECT_GT(env.solid_angle(j), 0);
    sum += env.solid_angle(j);
    EXPECT_EQ(env.Lookup(env.direction(j)), j) << "cell centre " << j;
    EXPECT_NEAR(env.direction(j).norm(), 1, 1e-12);
  }
  EXPECT_NEAR(sum, 4 * 3.14159265358979323846, 1e-9);
  Rng rng(3);
  for (int j = 0; j < env.size(); ++j)
    for (int s = 0; s < 8; ++s) {
      const double u1 = 0.001 + 0.998 * rng.Uniform(), u2 = 0.001 + 0.998 * rng.Uniform();
      EXPECT_EQ(env.Lookup(env.SampleInCell(j, u1, u2)), j);
    }
}

TEST_P(EnvMapRings, CellsAreNearestInPolarAngleAndSpacingIsRingSpacing) {
  const int R = GetParam();
  const EnvMap env(R, Eigen::Vector3d::UnitZ());
  const double dtheta = 3.14159265358979323846 / (R - 1);
  // Points within a ring are spaced at most the inter-ring spacing.
  for (int i = 1; i + 1 < R; ++i) {
    const double spacing = 2 * 3.14159265358979323846 * std::sin(i * dtheta) / env.ring_size(i);
    EXPECT_LE(spacing, dtheta + 1e-12);
    EXPECT_GT(spacing, dtheta * 0.5);
  }
  EXPECT_EQ(env.ring_size(0), 1);
  EXPECT_EQ(env.ring_size(R - 1), 1);
}

INSTANTIATE_TEST_SUITE_P(Rings, EnvMapRings, ::testing::Values(9, 15, 21, 31, 61));

// The neighbours' weights make a discrete Dirichlet energy: for f = the cosine of the polar
// angle about the rings' axis (a linear function) the integral of |grad f|^2 over the sphere is
// that of sin^2, 8 pi / 3, and the same for the cosine about another axis; every cell has at
// least two neighbours.
TEST_P(EnvMapRings, AdjacencyIsADirichletEnergy) {
  const int R = GetParam();
  const EnvMap env(R, Eigen::Vector3d(0.3, -1, 0.2));
  const std::vector<EnvMap::Neighbours> pairs = env.Adjacency();
  std::vector<int> degree(env.size(), 0);
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -0.5).normalized();
  double along_up = 0, along_axis = 0;
  for (const EnvMap::Neighbours& e : pairs) {
    ASSERT_LT(e.a, e.b);
    ASSERT_GT(e.weight, 0);
    ++degree[e.a], ++degree[e.b];
    along_up += e.weight * std::pow(env.direction(e.a).dot(env.up()) - env.direction(e.b).dot(env.up()), 2);
    along_axis += e.weight * std::pow(env.direction(e.a).dot(axis) - env.direction(e.b).dot(axis), 2);
  }
  for (int j = 0; j < env.size(); ++j) EXPECT_GE(degree[j], 2) << "cell " << j;
  const double exact = 8 * 3.14159265358979323846 / 3;
  // Along the rings' axis the error falls with the rings (measured -1.3 % at 9 rings, -0.2 % at
  // 21, -0.02 % at 61); across it a neighbour in the next ring is off in azimuth, so its
  // difference holds some of the other direction's and the energy comes out 3-5 % high at any
  // ring count (a prior's weight, which the data choose: no need of better).
  EXPECT_NEAR(along_up, exact, (R >= 21 ? 0.005 : 0.015) * exact) << R << " rings";
  EXPECT_NEAR(along_axis, exact, 0.06 * exact) << R << " rings";
  EXPECT_GT(along_axis, along_up) << R << " rings";
}

TEST(EnvMap, EquirectRoundTripOfPiecewiseConstantMap) {
  const EnvMap env(15, Eigen::Vector3d::UnitZ());
  std::vector<double> rgb(3 * env.size());
  for (int j = 0; j < env.size(); ++j)
    for (int c = 0; c < 3; ++c) rgb[3 * j + c] = j + 0.25 * c;
  // A fine equirect of the map integrates back to the same cell values (up to edge pixels).
  const ImageRGB img = env.ToEquirect(rgb, 512);
  const std::vector<double> back = env.FromEquirect(img, 16);
  int close = 0;
  for (int j = 0; j < env.size(); ++j) close += std::abs(back[3 * j] - rgb[3 * j]) < 0.5;
  EXPECT_GE(close, env.size() * 9 / 10);
}

TEST(EnvMap, UpAxisIsThePole) {
  const EnvMap env(21, Eigen::Vector3d(0, 0, 2));
  EXPECT_NEAR(env.direction(0).z(), 1, 1e-12);
  EXPECT_NEAR(env.direction(env.size() - 1).z(), -1, 1e-12);
  EXPECT_EQ(env.Lookup(Eigen::Vector3d(0, 0, 5)), 0);
}

// A light the estimate spread over many cells (lumpy, one cell 14 degrees off three times
// as bright as its neighbours) is found at the spread's centre, and a weaker second one
// 70 degrees away is found second.
TEST(DominantDirections, CentreOfASpreadLightThenTheNext) {
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const EnvMap env(21, up);
  const Eigen::Vector3d a = Eigen::Vector3d(0.55, 0.3, 0.78).normalized();
  const Eigen::Vector3d b = Eigen::Vector3d(0.1, -0.8, 0.6).normalized();
  ASSERT_NEAR(AngleDeg(a, b), 70, 10);
  Rng rng(5);
  std::vector<double> lambda(3 * env.size(), 0.0);
  int lump = -1;
  for (int j = 0; j < env.size(); ++j) {
    const double ta = AngleDeg(env.direction(j), a), tb = AngleDeg(env.direction(j), b);
    double v = 0;
    if (ta < 25) v += std::exp(-0.5 * ta * ta / 100) * (0.7 + 0.6 * rng.Uniform());
    if (tb < 10) v += 0.3 * std::exp(-0.5 * tb * tb / 16);
    if (lump < 0 && ta > 13 && ta < 16) lump = j, v *= 3;
    for (int c = 0; c < 3; ++c) lambda[3 * j + c] = v / env.solid_angle(j);
  }
  ASSERT_GE(lump, 0);
  const auto found = DominantDirections(env, lambda, 2);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_LT(AngleDeg(found[0], a), 4);
  EXPECT_LT(AngleDeg(found[1], b), 4);
  EXPECT_TRUE(DominantDirections(env, std::vector<double>(3 * env.size(), 0.0), 2).empty());
}

}  // namespace
}  // namespace lp
