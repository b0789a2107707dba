// Smoothing per-vertex values over a mesh's surface (SmoothOverSurface, FitAffineOverSurface)
// against values known in closed form.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "common/rng.h"
#include "scene/surface_filter.h"
#include "tests/test_util.h"

namespace lp {
namespace {

/// A value affine in the place and the normal, as the light a scan's surface receives is
/// to first order: it varies along the floor and with each vertex's tilt.
Eigen::Vector3f Affine(const Mesh& mesh, std::size_t v) {
  const Eigen::Vector3d p = mesh.positions[v].cast<double>(), n = mesh.normals[v].cast<double>();
  const double y = 1 + 0.6 * p.x() - 0.4 * p.y() + 0.5 * n.dot(Eigen::Vector3d(1, -0.5, 0).normalized());
  return Eigen::Vector3f(static_cast<float>(y), static_cast<float>(0.5 * y), static_cast<float>(2 - y));
}

struct Errors {
  double rms = 0, worst = 0, by_the_border = 0;  ///< relative; RMS over the vertices within 3 cm of an edge
};

Errors Against(const Mesh& mesh, const std::vector<Eigen::Vector3f>& got, const std::vector<Eigen::Vector3f>& truth) {
  Errors out;
  int border = 0;
  for (std::size_t v = 0; v < got.size(); ++v)
    for (int c = 0; c < 3; ++c) {
      const double e = got[v][c] / truth[v][c] - 1;
      out.rms += e * e;
      out.worst = std::max(out.worst, std::abs(e));
      if (std::max(std::abs(mesh.positions[v].x()), std::abs(mesh.positions[v].y())) > 0.47f) {
        out.by_the_border += e * e;
        ++border;
      }
    }
  out.rms = std::sqrt(out.rms / (3 * got.size()));
  out.by_the_border = std::sqrt(out.by_the_border / border);
  return out;
}

TEST(FitAffineOverSurface, AValueAffineInThePlaceAndTheNormalComesBackAsItWas) {
  // A 1 m floor, a vertex a centimetre, normals tilted by up to 10 degrees at random. With
  // the ridges off the fit is exact, at the floor's border too (a vertex's neighbours on one
  // side); with the defaults it stays far closer than SmoothOverSurface's mean, which mixes
  // the tilts' values and, at the border, the places'. Two fields fitted at once come out
  // as each alone.
  const Mesh mesh = test::FineFloor(0.5, 10 * M_PI / 180);
  std::vector<Eigen::Vector3f> truth(mesh.positions.size());
  for (std::size_t v = 0; v < truth.size(); ++v) truth[v] = Affine(mesh, v);
  SurfaceFilter off;
  off.place_ridge = off.normal_ridge = 1e-12;
  std::vector<Eigen::Vector3f> exact = truth, fit = truth, twice = truth;
  FitAffineOverSurface(mesh, {&exact}, off);
  std::vector<Eigen::Vector3f> other(truth.size(), Eigen::Vector3f(0.3f, 0.2f, 0.1f));
  FitAffineOverSurface(mesh, {&fit}, SurfaceFilter{});
  FitAffineOverSurface(mesh, {&other, &twice}, SurfaceFilter{});
  const Errors e0 = Against(mesh, exact, truth), e1 = Against(mesh, fit, truth),
               mean = Against(mesh, SmoothOverSurface(mesh, truth), truth);
  std::printf("ridges off: RMS %.5f %%, worst %.5f %%; defaults: RMS %.3f %% (border %.3f %%), worst %.3f %%; the mean: "
              "RMS %.3f %% (border %.3f %%), worst %.3f %%\n",
              100 * e0.rms, 100 * e0.worst, 100 * e1.rms, 100 * e1.by_the_border, 100 * e1.worst, 100 * mean.rms,
              100 * mean.by_the_border, 100 * mean.worst);
  EXPECT_LT(e0.worst, 1e-4);
  EXPECT_LT(e1.rms, mean.rms / 3);
  EXPECT_LT(e1.by_the_border, mean.by_the_border / 3);
  for (std::size_t v = 0; v < truth.size(); ++v) {
    EXPECT_FLOAT_EQ(twice[v].x(), fit[v].x()) << v;
    EXPECT_NEAR(other[v].x(), 0.3f, 1e-5f) << v;  // a constant stays itself
  }
}

TEST(FitAffineOverSurface, TakesNoiseOutAndLeavesWhatItCannotUse) {
  // 5 % noise over the affine value falls to under a third; a vertex without a usable normal
  // (never traced) keeps its value, and a crease (normals 90 degrees apart) is not crossed:
  // two floors at different levels' values stay their own.
  Mesh mesh = test::FineFloor(0.5, 10 * M_PI / 180);
  Rng rng(5);
  std::vector<Eigen::Vector3f> truth(mesh.positions.size()), noisy(truth.size());
  for (std::size_t v = 0; v < truth.size(); ++v) {
    truth[v] = Affine(mesh, v);
    noisy[v] = truth[v] * static_cast<float>(1 + 0.05 * std::sqrt(12.0) * (rng.Uniform() - 0.5));
  }
  mesh.normals[5050] = Eigen::Vector3f::Zero();
  const float kept = noisy[5050].x();
  FitAffineOverSurface(mesh, {&noisy});
  EXPECT_EQ(noisy[5050].x(), kept);
  noisy[5050] = truth[5050];
  const Errors e = Against(mesh, noisy, truth);
  std::printf("5 %% noise: %.3f %% left (border %.3f %%)\n", 100 * e.rms, 100 * e.by_the_border);
  EXPECT_LT(e.rms, 0.05 / 3);

  Mesh wall = test::FineFloor(0.5);
  for (std::size_t v = 0; v < wall.positions.size(); ++v) {  // the floor folded up at x = 0
    Eigen::Vector3f& p = wall.positions[v];
    if (p.x() > 0) {
      p = Eigen::Vector3f(0, p.y(), p.x());
      wall.normals[v] = Eigen::Vector3f(-1, 0, 0);
    }
  }
  std::vector<Eigen::Vector3f> two(wall.positions.size());
  for (std::size_t v = 0; v < two.size(); ++v)
    two[v] = Eigen::Vector3f::Constant(wall.normals[v].x() < -0.5f ? 2.f : 1.f);
  FitAffineOverSurface(wall, {&two});
  double worst = 0;
  for (std::size_t v = 0; v < two.size(); ++v)
    if (wall.positions[v].x() < -0.0001f || wall.positions[v].z() > 0.0001f)  // (the fold's own vertices aside)
      worst = std::max(worst, std::abs(two[v].x() - (wall.normals[v].x() < -0.5f ? 2.0 : 1.0)));
  EXPECT_LT(worst, 1e-5);
}

TEST(FitAffineOverSurface, SaysWhatItWasGivenWrong) {
  const Mesh mesh = test::FineFloor(0.5);
  std::vector<Eigen::Vector3f> few(3);
  EXPECT_THROW(FitAffineOverSurface(mesh, {&few}), std::exception);
}

}  // namespace
}  // namespace lp
