// How well the images fix a light (estimation/light_uncertainty.h): the sandwich covariance
// against the spread of refits over noise drawn again (its definition, measured), and the
// shape of a far lamp's region (long along its ray: the intensity-distance valley).
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "estimation/light_fit.h"
#include "estimation/light_uncertainty.h"
#include "estimation/sampling.h"
#include "scene/ray_tracer.h"
#include "tests/test_util.h"

namespace lp {
namespace {

struct Scene {
  RayTracer tracer{test::Merge(test::Plane(4, 0.7), test::Ball(0.3, 0.5))};
  ShadingVertices vertices;
  explicit Scene(const Eigen::Vector3d& eye = {1.5, -1.5, 1.5}) {
    TracerOptions o;
    o.spp = 4;
    o.bounces = 2;
    vertices = GatherShadingVertices(tracer, {test::BlankView(test::LookAt(eye, {0, 0, 0.1}, 48, 36, 50))}, o);
  }
  std::vector<double> Image(const PointLight& lamp) const {
    std::vector<float> col;
    UnitColumn(tracer, vertices, Light{lamp}, &col);
    std::vector<double> y(col.size());
    for (std::size_t i = 0; i < y.size(); ++i) y[i] = lamp.intensity[i % 3] * col[i];
    return y;
  }
};

std::vector<double> WithNoise(std::vector<double> y, double sigma, std::mt19937* rng) {
  std::normal_distribution<double> noise(0, sigma);
  for (double& v : y) v += noise(*rng);
  return y;
}

/// The lamp refitted on `trials` draws of independent noise (`noise` of the clean image's
/// mean on every pixel) and the covariance computed on the first draw (each pixel its own
/// block): (the refits' spread, the prediction).
std::pair<Eigen::Matrix3d, Eigen::Matrix3d> SpreadAndPrediction(const Scene& scene, const PointLight& lamp,
                                                                 double noise_share, int trials,
                                                                 std::vector<Eigen::Vector3d>* found) {
  const std::vector<double> clean = scene.Image(lamp);
  double mean = 0;
  for (double v : clean) mean += v / clean.size();
  const double noise = noise_share * mean;
  const std::vector<double> zero(clean.size(), 0.0);
  std::mt19937 rng(7);
  Eigen::Matrix3d predicted = Eigen::Matrix3d::Zero();
  std::vector<int> own_block(scene.vertices.rows());
  for (std::size_t r = 0; r < own_block.size(); ++r) own_block[r] = static_cast<int>(r);
  for (int trial = 0; trial < trials; ++trial) {
    const std::vector<double> y = WithNoise(clean, noise, &rng);
    const LightFitProblem fit{&scene.tracer, &scene.vertices, &y, &zero, CauchyLoss{20 * noise}, 0};
    std::vector<Light> lights{Light{lamp}};
    RefineLights(fit, &lights, 30);
    found->push_back(std::get<PointLight>(lights[0]).position);
    if (trial == 0) predicted = LightUncertainties(fit, lights, nullptr, {}, own_block)[0].shape_covariance;
  }
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : *found) centre += p / found->size();
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const auto& p : *found) spread += (p - centre) * (p - centre).transpose() / (found->size() - 1);
  return {spread, predicted};
}

double AxisAngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const Eigen::Vector3d u = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(a).eigenvectors().col(2);
  const Eigen::Vector3d v = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(b).eigenvectors().col(2);
  return std::acos(std::min(1.0, std::abs(u.dot(v)))) * 180 / kPi;
}

TEST(LightUncertainty, TheCovarianceIsTheSpreadOfRefitsOverNoiseDrawnAgain) {
  // Independent noise on every pixel (each its own block): the lamp refitted on 100 draws
  // of it scatters as the covariance computed from one draw says (a variance off by the
  // loss's weights, a wrong Jacobian or a missing parameter fails here); a near lamp and a
  // far one (whose region is long).
  const Scene scene;
  for (const PointLight& lamp : {PointLight{{0.5, 0.4, 1.2}, {3, 2.5, 2}, 0}, PointLight{{1.2, 0.6, 6.0}, {120, 100, 80}, 0}}) {
    std::vector<Eigen::Vector3d> found;
    const auto [spread, predicted] = SpreadAndPrediction(scene, lamp, 0.05, 100, &found);
    EXPECT_GT(predicted.trace(), 0.7 * spread.trace()) << predicted << "\nagainst\n" << spread;
    EXPECT_LT(predicted.trace(), 1.4 * spread.trace()) << predicted << "\nagainst\n" << spread;
    EXPECT_LT(AxisAngleDeg(spread, predicted), 10);
    // The same shape: the refits' Mahalanobis distances under it average 3 (the dimension).
    double m = 0;
    for (const auto& p : found) m += SquaredMahalanobis(p - lamp.position, predicted) / found.size();
    EXPECT_GT(m, 3 / 1.4);
    EXPECT_LT(m, 3 * 1.4);
  }
}

TEST(LightUncertainty, AFarLampsRegionIsLongAlongItsRay) {
  // A lamp 6 m above a small scene (seen from above, so that what is seen is centred on
  // the scene) lights it almost as a nearer, dimmer one would: its region is long along the
  // ray from the scene's centre (within 15 degrees) and at least 3 times as long as across.
  const Scene scene(Eigen::Vector3d(0.3, -0.2, 3.0));
  const PointLight lamp{{1.2, 0.6, 6.0}, {120, 100, 80}, 0};
  const std::vector<double> clean = scene.Image(lamp);
  double mean = 0;
  for (double v : clean) mean += v / clean.size();
  std::mt19937 rng(3);
  const std::vector<double> y = WithNoise(clean, 0.05 * mean, &rng);
  const std::vector<double> zero(y.size(), 0.0);
  const LightFitProblem fit{&scene.tracer, &scene.vertices, &y, &zero, CauchyLoss{mean}, 0};
  std::vector<int> blocks(scene.vertices.rows());
  for (std::size_t r = 0; r < blocks.size(); ++r) blocks[r] = static_cast<int>((r % 48) / 8 + 6 * ((r / 48) / 8));
  const LightUncertainty u = LightUncertainties(fit, {Light{lamp}}, nullptr, {}, blocks)[0];
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(u.shape_covariance);
  ASSERT_GT(eig.eigenvalues()[0], 0);
  const Eigen::Vector3d major = eig.eigenvectors().col(2);
  const Eigen::Vector3d ray = (lamp.position - scene.tracer.center()).normalized();
  EXPECT_LT(std::acos(std::abs(major.dot(ray))) * 180 / kPi, 15) << major.transpose();
  EXPECT_GT(std::sqrt(eig.eigenvalues()[2] / eig.eigenvalues()[0]), 3) << eig.eigenvalues().transpose();
  EXPECT_GT(u.scale_sigma.minCoeff(), 0);
}

TEST(LightUncertainty, ALightNoPixelSeesIsUnknownAndTheOtherStaysKnown) {
  // A second lamp under the floor lights nothing the camera sees: its place and intensity
  // are unknown (infinite), and the lamp above keeps a finite region.
  const Scene scene;
  const PointLight lamp{{0.5, 0.4, 1.2}, {3, 2.5, 2}, 0}, hidden{{0.3, 0.2, -1.0}, {1, 1, 1}, 0};
  std::mt19937 rng(5);
  std::vector<double> y = scene.Image(lamp);
  double mean = 0;
  for (double v : y) mean += v / y.size();
  y = WithNoise(y, 0.05 * mean, &rng);
  const std::vector<double> zero(y.size(), 0.0);
  const LightFitProblem fit{&scene.tracer, &scene.vertices, &y, &zero, CauchyLoss{mean}, 0};
  std::vector<int> blocks(scene.vertices.rows());
  for (std::size_t r = 0; r < blocks.size(); ++r) blocks[r] = static_cast<int>(r % 24);
  const std::vector<LightUncertainty> u = LightUncertainties(fit, {Light{lamp}, Light{hidden}}, nullptr, {}, blocks);
  ASSERT_EQ(u.size(), 2u);
  EXPECT_TRUE(u[0].shape_covariance.allFinite());
  EXPECT_TRUE(u[0].scale_sigma.allFinite());
  EXPECT_FALSE(u[1].shape_covariance.allFinite());
  EXPECT_FALSE(u[1].scale_sigma.allFinite());
}

TEST(LightUncertainty, SquaredMahalanobisIsTheClosedForm) {
  Eigen::Matrix3d cov = Eigen::Vector3d(4, 1, 0.25).asDiagonal();
  EXPECT_NEAR(SquaredMahalanobis({2, 1, 0.5}, cov), 3, 1e-12);
  cov(2, 2) = 0;  // a direction's: nothing along its normal
  EXPECT_NEAR(SquaredMahalanobis({2, 1, 5}, cov), 2, 1e-12);
  cov.setConstant(INFINITY);
  EXPECT_EQ(SquaredMahalanobis({1, 1, 1}, cov), 0);
}

// The polish's rule (docs/method.md, "The lamps polished"): how many times the paths'
// covariance exceeds the images' where it does most. Closed forms: diagonal pairs give the
// largest ratio of their diagonals; a rotation of both changes nothing; a covariance the
// images do not bound (infinite, singular) gives 0, never a spurious polish.
TEST(LightUncertainty, LargestVarianceRatioIsTheLargestRatioOverDirections) {
  const Eigen::Matrix3d paths = Eigen::Vector3d(1, 8, 0.5).asDiagonal();
  const Eigen::Matrix3d images = Eigen::Vector3d(4, 2, 0.1).asDiagonal();
  EXPECT_NEAR(LargestVarianceRatio(paths, images), 5, 1e-12);  // max(0.25, 4, 5)
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  EXPECT_NEAR(LargestVarianceRatio(r * paths * r.transpose(), r * images * r.transpose()), 5, 1e-9);
  // A paths' covariance of rank one along u: its ratio is uᵀ P u / uᵀ D u only if u is an
  // axis of D; in general uᵀ D⁻¹ u times its variance.
  const Eigen::Vector3d u = Eigen::Vector3d(1, 1, 0).normalized();
  const Eigen::Matrix3d one = 3 * u * u.transpose();
  EXPECT_NEAR(LargestVarianceRatio(one, images), 3 * u.dot(images.inverse() * u), 1e-12);
  EXPECT_EQ(LargestVarianceRatio(Eigen::Matrix3d::Zero(), images), 0);
  Eigen::Matrix3d singular = images;
  singular(2, 2) = 0;
  EXPECT_EQ(LargestVarianceRatio(paths, singular), 0);
  EXPECT_EQ(LargestVarianceRatio(paths, Eigen::Matrix3d::Constant(INFINITY)), 0);
}

}  // namespace
}  // namespace lp
