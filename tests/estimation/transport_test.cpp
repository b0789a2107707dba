// Closed forms for the path tracer and the transport matrix.
#include <atomic>
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "common/parallel.h"
#include "estimation/path_tracer.h"
#include "tests/test_util.h"

namespace lp {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::vector<double> OneCell(const EnvMap& env, int j, double v = 1) {
  std::vector<double> l(3 * env.size(), 0.0);
  for (int c = 0; c < 3; ++c) l[3 * j + c] = v;
  return l;
}

double MeanOfImage(const ImageRGB& img, int c = 0) {
  double s = 0;
  for (std::size_t i = 0; i < img.pixels(); ++i) s += img.data[3 * i + c];
  return s / img.pixels();
}

/// rho/pi * integral over cell j of max(0, cos theta) d omega, by fine quadrature.
double PlaneUnderCell(const EnvMap& env, int j, double rho) {
  const int n = 200;
  double sum = 0;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) sum += std::max(0.0, env.SampleInCell(j, (a + 0.5) / n, (b + 0.5) / n).z());
  return rho / kPi * env.solid_angle(j) * sum / (n * n);
}

TEST(Transport, LambertianPlaneUnderOneCellMatchesClosedForm) {
  const double rho = 0.6;
  RayTracer scene([&] { Mesh m = test::Plane(2000, rho); return m; }());
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  std::vector<View> views{test::BlankView(test::LookAt({0, 0, 1}, {0, 0, 0}, 8, 8, 10))};
  TracerOptions opt;
  opt.spp = 512;
  opt.bounces = 1;
  for (int j : {0, 30, 100, 200}) {
    const std::vector<double> lambda = OneCell(env, j);
    CellSampler sampler(env, lambda, {}, 0.2);
    const auto img = RenderEnvironment(scene, env, views, lambda, sampler, opt, true);
    const double expected = PlaneUnderCell(env, j, rho);
    ASSERT_GT(expected, 0) << "cell " << j << " must be above the horizon";
    EXPECT_NEAR(MeanOfImage(img[0]), expected, 0.02 * expected) << "cell " << j;
  }
}

TEST(Transport, CellBelowTheHorizonGivesExactlyZero) {
  RayTracer scene(test::Plane(2000, 0.6));
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  std::vector<View> views{test::BlankView(test::LookAt({0, 0, 1}, {0, 0, 0}, 8, 8, 10))};
  TracerOptions opt;
  opt.spp = 64;
  const TransportMatrix A = TraceTransport(scene, env, views, CellSampler(env, {}, {}, 0.2), opt);
  const std::vector<int> counts = A.ColumnCounts();
  for (int j = 0; j < env.size(); ++j)
    if (env.direction(j).z() < -0.2) {
      EXPECT_EQ(counts[j], 0) << "cell " << j;
    }
}

TEST(Transport, WhiteFurnaceConvexAlbedoOneIsUniform) {
  RayTracer scene(test::Ball(1.0, 1.0));
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  std::vector<View> views{test::BlankView(test::LookAt({0, -4, 0.5}, {0, 0, 0}, 24, 24, 40))};
  TracerOptions opt;
  opt.spp = 128;
  opt.bounces = 4;
  const std::vector<double> lambda(3 * env.size(), 1.0);
  const auto img = RenderEnvironment(scene, env, views, lambda, CellSampler(env, lambda, {}, 0.2), opt, true);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(MeanOfImage(img[0], c), 1.0, 0.01);
  for (float v : img[0].data) EXPECT_NEAR(v, 1.0, 0.15);
}

TEST(Transport, ShadowedPointReceivesNothingFromTheBlockedCell) {
  Mesh m = test::Plane(2000, 0.6);
  m.Append(test::Square(0, 0, 0.5, 0.5, 0.6));
  RayTracer shadowed(m);
  RayTracer open(test::Plane(2000, 0.6));
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  std::vector<View> views{test::BlankView(test::LookAt({0.3, 0, 0.2}, {0, 0, 0}, 8, 8, 8))};
  TracerOptions opt;
  opt.spp = 256;
  opt.bounces = 1;
  const std::vector<double> lambda = OneCell(env, 0);
  CellSampler sampler(env, lambda, {}, 0.2);
  const auto dark = RenderEnvironment(shadowed, env, views, lambda, sampler, opt, true);
  const auto lit = RenderEnvironment(open, env, views, lambda, sampler, opt, true);
  EXPECT_EQ(MeanOfImage(dark[0]), 0.0);
  EXPECT_NEAR(MeanOfImage(lit[0]), PlaneUnderCell(env, 0, 0.6), 0.03 * PlaneUnderCell(env, 0, 0.6));
}

TEST(Transport, MatrixTimesLambdaEqualsDirectRender) {
  Mesh m = test::Plane(6, 0.7);
  Mesh ball = test::Ball(0.5, 0.8, 16, 32);
  for (auto& p : ball.positions) p.z() += 0.5f;
  m.Append(ball);
  RayTracer scene(m);
  const EnvMap env(15, Eigen::Vector3d::UnitZ());
  std::vector<View> views{test::BlankView(test::LookAt({2.5, -2, 1.5}, {0, 0, 0.3}, 32, 24, 50))};
  std::vector<double> lambda(3 * env.size());
  for (int j = 0; j < env.size(); ++j)
    for (int c = 0; c < 3; ++c) lambda[3 * j + c] = 0.1 + std::fmod(0.37 * j + 0.11 * c, 1.0);
  CellSampler sampler(env, lambda, {}, 0.2);
  TracerOptions opt;
  opt.spp = 8;
  opt.bounces = 3;
  const TransportMatrix A = TraceTransport(scene, env, views, sampler, opt);
  const std::vector<double> Al = A.Multiply(lambda);
  const auto img = RenderEnvironment(scene, env, views, lambda, sampler, opt, false);
  ASSERT_EQ(A.rows(), img[0].pixels());
  double max_rel = 0;
  for (std::size_t r = 0; r < A.rows(); ++r)
    for (int c = 0; c < 3; ++c) {
      const double direct = img[0].data[3 * A.row_pixel[r] + c];
      max_rel = std::max(max_rel, std::abs(Al[3 * r + c] - direct) / std::max(1e-6, std::abs(direct)));
    }
  EXPECT_LT(max_rel, 1e-5);
}

TEST(Transport, SameSeedIsBitIdenticalForAnyThreadCount) {
  Mesh m = test::Plane(6, 0.7);
  m.Append(test::Square(0, 0, 0.5, 0.3, 0.5));
  RayTracer scene(m);
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  std::vector<View> views{test::BlankView(test::LookAt({2.5, -2, 1.5}, {0, 0, 0.3}, 40, 30, 50))};
  TracerOptions opt;
  opt.spp = 8;
  auto trace = [&](int threads) {
    ThreadLimit limit(threads);
    return TraceTransport(scene, env, views, CellSampler(env, {}, {}, 0.2), opt);
  };
  const TransportMatrix a = trace(1), b = trace(2), c = trace(0);
  ASSERT_EQ(a.col, b.col);
  ASSERT_EQ(a.col, c.col);
  ASSERT_EQ(a.val.size(), b.val.size());
  EXPECT_EQ(std::memcmp(a.val.data(), b.val.data(), a.val.size() * sizeof(a.val[0])), 0);
  EXPECT_EQ(std::memcmp(a.val.data(), c.val.data(), a.val.size() * sizeof(a.val[0])), 0);
}

// A cancelled trace stops at the next chunk of 64 pixels: cancelled from the start nothing
// is traced; cancelled after 5 checks, exactly 5 chunks are.
TEST(Transport, ACancelledTraceStopsEarly) {
  RayTracer scene(test::Plane(6, 0.7));
  const EnvMap env(9, Eigen::Vector3d::UnitZ());
  std::vector<View> views{test::BlankView(test::LookAt({0, 0, 2}, {0, 0, 0}, 64, 48, 50))};  // 48 chunks
  TracerOptions opt;
  opt.spp = 2;
  TraceStats all, none, some;
  TraceTransport(scene, env, views, CellSampler(env, {}, {}, 0.2), opt, &all);
  EXPECT_EQ(all.paths, 64 * 48 * 2);
  opt.cancelled = [] { return true; };
  TraceTransport(scene, env, views, CellSampler(env, {}, {}, 0.2), opt, &none);
  EXPECT_EQ(none.paths, 0);
  std::atomic<int> checks{0};
  opt.cancelled = [&checks] { return ++checks > 5; };
  TraceTransport(scene, env, views, CellSampler(env, {}, {}, 0.2), opt, &some);
  // Each chunk of 64 pixels asks once before it starts: exactly the first 5 run, whichever
  // threads ask (64x48 pixels are 48 full chunks).
  EXPECT_EQ(some.paths, 5 * 64 * 2);
}

TEST(Transport, MaskedPixelsAreNotTraced) {
  RayTracer scene(test::Plane(10, 0.5));
  const EnvMap env(9, Eigen::Vector3d::UnitZ());
  View v = test::BlankView(test::LookAt({0, 0, 1}, {0, 0, 0}, 10, 10, 30));
  for (std::size_t i = 0; i < v.valid.size(); i += 2) v.valid[i] = 0;
  TraceStats stats;
  const TransportMatrix A = TraceTransport(scene, env, {v}, CellSampler(env, {}, {}, 0.2), TracerOptions(), &stats);
  EXPECT_EQ(A.rows(), 50u);
  EXPECT_EQ(stats.pixels_traced, 50);
  EXPECT_EQ(stats.pixels_skipped, 50);
}

}  // namespace
}  // namespace lp
