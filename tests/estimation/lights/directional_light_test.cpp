// A directional light (estimation/lights/directional_light.h): its column's derivative on
// the sphere against central differences. (Its shape coordinates, compass moves and
// irradiance against closed forms: light_fit_test, beside the lamp's.)
#include <cmath>

#include <gtest/gtest.h>

#include "estimation/lights/light.h"
#include "scene/scene_bundle.h"
#include "tests/estimation/lights/plane_and_ball.h"
#include "tests/test_util.h"

namespace lp {
namespace {

TEST(PointLights, TheDirectionDerivativeMatchesCentralDifferences) {
  // A directional light's column against its direction moved on the sphere (towards + d,
  // normalized): a plane and a ball, the light high enough that no shadow edge moves within h.
  const test::PlaneAndBall pb(24, 18, 50, 2);
  const RayTracer& scene = pb.scene;
  const ShadingVertices& v = pb.vertices;
  const Eigen::Vector3d l = Eigen::Vector3d(0.3, 0.4, 1.0).normalized();
  std::vector<float> col, jac, plus, minus;
  DirectionalLightColumn(scene, v, l, &col, &jac);
  const double h = 1e-4;
  double worst = 0, scale = 0;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[a] = h;
    DirectionalLightColumn(scene, v, (l + d).normalized(), &plus);
    DirectionalLightColumn(scene, v, (l - d).normalized(), &minus);
    for (std::size_t r = 0; r < v.rows(); ++r)
      for (int c = 0; c < 3; ++c) {
        const double fd = (double(plus[3 * r + c]) - minus[3 * r + c]) / (2 * h);
        worst = std::max(worst, std::abs(fd - jac[9 * r + 3 * c + a]));
        scale = std::max(scale, std::abs(fd));
      }
  }
  EXPECT_GT(scale, 0);
  EXPECT_LT(worst, 2e-2 * scale) << "worst " << worst << " of " << scale;
}

// The column traces each chunk's shadow rays as one stream (RayTracer::OccludedMany): it
// must see what ConeVisibility sees ray by ray, for a sharp sun and for one with a disc whose
// penumbra the ball casts on the plane.
TEST(DirectionalLights, TheColumnSeesWhatEachVertexsShadowRaysSee) {
  const test::PlaneAndBall pb(24, 18, 50, 2);
  const ShadingVertices& v = pb.vertices;
  const Eigen::Vector3d l = Eigen::Vector3d(-0.5, 0.6, 0.7).normalized();
  for (double radius : {0.0, 0.1}) {
    std::vector<float> col;
    DirectionalLightColumn(pb.scene, v, l, &col, nullptr, radius);
    double scale = 0, shaded = 0;
    const double worst = test::WorstColumnDifference(v, col, [&](std::int64_t k) {
      const double cn = v.normal[k].cast<double>().dot(l);
      if (!(cn > 0 && v.geometric[k].cast<double>().dot(l) > 0)) return Eigen::Vector3d::Zero().eval();
      const double seen =
          ConeVisibility(pb.scene, v.position[k].cast<double>(), l, radius, static_cast<std::uint64_t>(k));
      shaded += seen < 1;
      return Eigen::Vector3d(v.weight[k].cast<double>() * seen * cn);
    }, &scale);
    EXPECT_GT(scale, 0);
    EXPECT_LT(worst, 1e-5 * scale) << "radius " << radius << ": worst " << worst << " of " << scale;
    EXPECT_GT(shaded, 0) << radius;  // the ball shadows some vertices
  }
}

}  // namespace
}  // namespace lp
