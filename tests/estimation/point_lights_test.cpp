// Point lights (the near-light model): the forward model against closed forms, the
// column's position derivative against central differences, and the position refinement.
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/error.h"
#include "estimation/lights_file.h"
#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "estimation/sampling.h"
#include "estimation/truth.h"
#include "scene/scene_bundle.h"
#include "tests/test_util.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

/// Outgoing radiance of a Lambertian point (albedo rho) under a point light of intensity I:
/// rho / pi x I cos(theta) / d^2.
double PlaneRadiance(double rho, double I, const Eigen::Vector3d& x, const Eigen::Vector3d& light) {
  const Eigen::Vector3d r = light - x;
  const double d = r.norm(), c = r.z() / d;
  return rho / kPi * I * c / (d * d);
}

TEST(PointLights, LambertianPlaneMatchesTheClosedFormAtTwoDistances) {
  const double rho = 0.6, I = 2.0;
  RayTracer scene(test::Plane(4, rho));
  const Camera cam = test::LookAt({0.3, -0.2, 3}, {0.3, -0.2, 0}, 32, 24, 40);
  std::vector<View> views{test::BlankView(cam)};
  TracerOptions o;
  o.spp = 1024;
  o.bounces = 1;
  for (double h : {0.5, 1.0}) {  // inverse square: 4x brighter below the light at half the height
    const Eigen::Vector3d light(0.1, 0.2, h);
    const std::vector<ImageRGB> img = RenderPointLights(scene, views, {{light, Eigen::Vector3d::Constant(I), 0}}, o, true);
    for (int y = 2; y < cam.height; y += 7)
      for (int x = 3; x < cam.width; x += 9) {
        // The closed form averaged over the pixel's square (8 x 8 points), as the jitter does.
        double expect = 0;
        for (int i = 0; i < 8; ++i)
          for (int j = 0; j < 8; ++j) {
            SurfacePoint hit;
            ASSERT_TRUE(scene.Intersect(cam.center(), cam.RayDirection(x - 0.5 + (i + 0.5) / 8, y - 0.5 + (j + 0.5) / 8), &hit));
            expect += PlaneRadiance(rho, I, hit.position, light) / 64;
          }
        EXPECT_NEAR(img[0].at(x, y)[0], expect, 0.005 * expect) << "h " << h << " pixel " << x << "," << y;
      }
  }
}

TEST(PointLights, ABoxLidCastsItsShadowOntoTheFloor) {
  // A square lid (half-side 0.3) 0.4 m above the floor and a light at (1, 0, 2): a floor
  // point p is in shadow exactly when the line to the light crosses the lid, at
  // 0.8 p + 0.2 light (z = 0.4).
  const Eigen::Vector3d light(1, 0, 2);
  RayTracer scene(test::Merge(test::Plane(6, 0.5), test::Square(0, 0, 0.4, 0.3, 0.5)));
  const Camera cam = test::LookAt({0.8, -1.0, 1.5}, {-0.3, 0, 0}, 64, 48, 70);
  std::vector<View> views{test::BlankView(cam)};
  TracerOptions o;
  o.spp = 1;
  o.bounces = 1;
  const ImageRGB img = RenderPointLights(scene, views, {{light, Eigen::Vector3d::Ones(), 0}}, o, true)[0];
  int lit = 0, shadowed = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      SurfacePoint hit;
      if (!scene.Intersect(cam.center(), cam.RayDirection(x, y), &hit) || hit.position.z() > 0.1 ||
          hit.position.cwiseAbs().maxCoeff() > 2.5)  // the lid, or near the floor's edge
        continue;
      bool floor_only = true;  // the jittered rays might hit the lid beside the floor
      for (double dx : {-0.5, 0.5})
        for (double dy : {-0.5, 0.5}) {
          SurfacePoint corner;
          floor_only = floor_only && scene.Intersect(cam.center(), cam.RayDirection(x + dx, y + dy), &corner) &&
                       corner.position.z() < 0.1;
        }
      if (!floor_only) continue;
      const Eigen::Vector3d at_lid = 0.8 * hit.position + 0.2 * light;
      const double m = std::max(std::abs(at_lid.x()), std::abs(at_lid.y()));
      if (std::abs(m - 0.3) < 0.05) continue;  // a pixel's footprint straddles the edge
      const float v = img.at(x, y)[0];
      if (m < 0.3) {
        EXPECT_EQ(v, 0.0f) << x << "," << y;
        ++shadowed;
      } else {
        EXPECT_GT(v, 0.0f) << x << "," << y;
        ++lit;
      }
    }
  EXPECT_GT(shadowed, 50);
  EXPECT_GT(lit, 50);
}

// A lamp of radius 0.1 m 1 m above the floor, half of it hidden from the floor below by a
// half-plane 0.5 m up whose edge runs under its centre: a floor point at x sees the lamp
// through the half-plane's edge, which cuts its disc at sx = -x; the share seen is the area of
// the disc's segment beyond that chord (closed form), averaged over many vertices' patterns.
TEST(PointLights, ASphereLightsPenumbraIsTheDiscsVisibleSegment) {
  const RayTracer scene(test::Square(-1.0, 0.0, 0.5, 1.0, 0.5));
  const Eigen::Vector3d q(0, 0, 1);
  const double r = 0.1;
  auto segment = [&](double t) {  // share of the disc of radius r with sx > t
    if (t >= r) return 0.0;
    if (t <= -r) return 1.0;
    return (r * r * std::acos(t / r) - t * std::sqrt(r * r - t * t)) / (M_PI * r * r);
  };
  for (double x : {-0.15, -0.05, 0.0, 0.05, 0.15}) {
    const Eigen::Vector3d p(x, 0, 0);
    const Eigen::Vector3d to = q - p;
    const double d = to.norm();
    double seen = 0, single = 0;
    const int n = 4096;
    for (int k = 0; k < n; ++k) {
      seen += SphereVisibility(scene, p, q, r, to / d, d, k);
      single += SphereVisibility(scene, p, q, r, to / d, d, k, 1);
    }
    seen /= n;
    single /= n;
    std::printf("x %+.2f: seen %.4f (one ray per key %.4f), the disc's segment %.4f\n", x, seen, single, segment(-x));
    EXPECT_NEAR(seen, segment(-x), 0.02) << x;
    EXPECT_NEAR(single, segment(-x), 0.02) << x;
  }
  // A point light there is all or nothing.
  EXPECT_EQ(SphereVisibility(scene, {-0.05, 0, 0}, q, 0, (q - Eigen::Vector3d(-0.05, 0, 0)).normalized(),
                             (q - Eigen::Vector3d(-0.05, 0, 0)).norm(), 7),
            0.0);
}

TEST(PointLights, ThePositionDerivativeMatchesCentralDifferences) {
  RayTracer scene(test::Merge(test::Plane(4, 0.7), test::Ball(0.3, 0.5)));
  const Camera cam = test::LookAt({1.5, -1.5, 1.5}, {0, 0, 0.1}, 24, 18, 50);
  std::vector<View> views{test::BlankView(cam)};
  TracerOptions o;
  o.spp = 2;
  o.bounces = 2;
  const ShadingVertices v = GatherShadingVertices(scene, views, o);
  ASSERT_GT(v.size(), 0u);
  const Eigen::Vector3d q(0.4, 0.9, 1.3);  // high enough that no shadow edge moves within h
  std::vector<float> col, jac, plus, minus;
  PointLightColumn(scene, v, q, &col, &jac);
  const double h = 1e-3;
  double worst = 0, scale = 0;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d dq = Eigen::Vector3d::Zero();
    dq[a] = h;
    PointLightColumn(scene, v, q + dq, &plus);
    PointLightColumn(scene, v, q - dq, &minus);
    for (std::size_t r = 0; r < v.rows(); ++r)
      for (int c = 0; c < 3; ++c) {
        const double fd = (double(plus[3 * r + c]) - minus[3 * r + c]) / (2 * h);
        worst = std::max(worst, std::abs(fd - jac[9 * r + 3 * c + a]));
        scale = std::max(scale, std::abs(fd));
      }
  }
  EXPECT_GT(scale, 0);
  EXPECT_LT(worst, 2e-3 * scale) << "worst " << worst << " of " << scale;  // float columns: ~1e-4 measured
}

TEST(PointLights, TheDirectionDerivativeMatchesCentralDifferences) {
  // A directional light's column against its direction moved on the sphere (towards + d,
  // normalized): a plane and a ball, the light high enough that no shadow edge moves within h.
  RayTracer scene(test::Merge(test::Plane(4, 0.7), test::Ball(0.3, 0.5)));
  const Camera cam = test::LookAt({1.5, -1.5, 1.5}, {0, 0, 0.1}, 24, 18, 50);
  std::vector<View> views{test::BlankView(cam)};
  TracerOptions o;
  o.spp = 2;
  o.bounces = 2;
  const ShadingVertices v = GatherShadingVertices(scene, views, o);
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

TEST(PointLights, RefinementFindsTheLampFromHalfAMetreAway) {
  // The lamp of a plane and a ball rendered by the forward model; the refinement starts
  // 0.5 m off with the wrong intensity and must come back (positions to 1 cm).
  RayTracer scene(test::Merge(test::Plane(4, 0.7), test::Ball(0.3, 0.5)));
  const Camera cam = test::LookAt({1.5, -1.5, 1.5}, {0, 0, 0.1}, 40, 30, 60);
  std::vector<View> views{test::BlankView(cam)};
  TracerOptions o;
  o.spp = 8;
  o.bounces = 2;
  const PointLight lamp{{0.5, 0.4, 1.2}, {3, 2.5, 2}, 0};
  const ShadingVertices v = GatherShadingVertices(scene, views, o);
  std::vector<float> col;
  PointLightColumn(scene, v, lamp.position, &col);
  std::vector<double> y(col.size()), base(col.size(), 0.0);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] = lamp.intensity[i % 3] * col[i];
  const LightFitProblem fit{&scene, &v, &y, &base, CauchyLoss{0.5}, 0};  // no activation penalty
  std::vector<Light> lights{PointLight{lamp.position + Eigen::Vector3d(0.3, -0.3, 0.25), {1, 1, 1}, 0}};
  const int steps = RefineLights(fit, &lights, 40);
  const PointLight& found = std::get<PointLight>(lights[0]);
  EXPECT_GT(steps, 0);
  EXPECT_LT((found.position - lamp.position).norm(), 0.01) << found.position.transpose();
  EXPECT_LT((found.intensity - lamp.intensity).norm(), 0.02 * lamp.intensity.norm());
}

TEST(LightsFile, RoundTripsAndRefusesBadLights) {
  const LightsFile in{"envmap.exr", {{{1, 2, 3}, {0.5, 0.25, 0}, 0.05}}, {}};
  const LightsFile out = ParseLightsJson(LightsJson(in), "lights.json");
  EXPECT_EQ(out.environment, "envmap.exr");
  ASSERT_EQ(out.point_lights.size(), 1u);
  EXPECT_EQ(out.point_lights[0].position, in.point_lights[0].position);
  EXPECT_EQ(out.point_lights[0].intensity, in.point_lights[0].intensity);
  EXPECT_EQ(out.point_lights[0].radius, 0.05);
  EXPECT_TRUE(out.directional_lights.empty());
  EXPECT_NE(LightsJson(in).find("\"directional_lights\": []"), std::string::npos);  // always present
  // Directional lights: the direction is normalized, the rest kept.
  LightsFile sun;
  sun.directional_lights.push_back({{0, 3, 4}, {2, 1.5, 1}, 0.0046});
  const LightsFile back = ParseLightsJson(LightsJson(sun), "lights.json");
  ASSERT_EQ(back.directional_lights.size(), 1u);
  EXPECT_TRUE(back.directional_lights[0].direction.isApprox(Eigen::Vector3d(0, 0.6, 0.8), 1e-15));
  EXPECT_EQ(back.directional_lights[0].irradiance, Eigen::Vector3d(2, 1.5, 1));
  EXPECT_EQ(back.directional_lights[0].angular_radius, 0.0046);
  EXPECT_TRUE(back.point_lights.empty());
  // Unknown keys are ignored; no environment and no lights is an empty lighting, and a file
  // from before directional lights has none.
  const LightsFile empty = ParseLightsJson(R"({"point_lights": [], "directional_lights": [], "x": 1})", "x");
  EXPECT_TRUE(empty.environment.empty());
  EXPECT_TRUE(empty.point_lights.empty());
  EXPECT_TRUE(ParseLightsJson(R"({"point_lights": []})", "x").directional_lights.empty());
  for (const char* bad : {R"({"directional_lights": [{"direction": [0, 0, 0], "irradiance": [1, 1, 1]}]})",
                          R"({"directional_lights": [{"direction": [0, 0, 1], "irradiance": [1, -1, 1]}]})",
                          R"({"directional_lights": [{"direction": [0, 0, 1]}]})", R"({"directional_lights": 3})",
                          R"({"directional_lights": [{"direction": [0, 0, 1], "irradiance": [1, 1, 1], "angular_radius": 2}]})",
                          R"({"directional_lights": [{"direction": [0, 1e308, 1e308], "irradiance": [1, 1, 1]}]})"})
    EXPECT_THROW(ParseLightsJson(bad, "x"), InputError) << bad;
  for (const char* bad : {R"({"point_lights": [{"position": [0, 0], "intensity": [1, 1, 1]}]})",
                          R"({"point_lights": [{"position": [0, 0, 0], "intensity": [1, -1, 1]}]})",
                          R"({"point_lights": [{"intensity": [1, 1, 1]}]})", R"({"point_lights": {}})",
                          R"([1, 2])", R"({"point_lights": [{"position": [0, 0, 0], "intensity": [1, 1, 1], "radius": -1}]})"})
    EXPECT_THROW(ParseLightsJson(bad, "x"), InputError) << bad;
}

TEST(Truth, ReadsALampGivenByItsPosition) {
  // The Cycles bundle's truth.json: a point light by position and radiant intensity, the
  // scene centre in scene_bbox, no direction.
  const fs::path dir = fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data" / "cycles" / "cornerbox_one_light";
  const std::vector<TruthLight> t = ParseTruthLights(ReadTextFile(dir / "truth.json"), "truth.json");
  ASSERT_EQ(t.size(), 1u);
  ASSERT_TRUE(t[0].position.has_value());
  EXPECT_NEAR((*t[0].position - Eigen::Vector3d(1.0, 0.45, 2.25)).norm(), 0, 1e-6);
  // Direction from the centre (0, 0, 0.8): (1, 0.45, 1.45) / 1.8180 (truth.json's own
  // direction_from_bbox_centre, 0.5501 0.2475 0.7976).
  EXPECT_NEAR(t[0].direction.x(), 0.550065, 1e-5);
  EXPECT_NEAR(t[0].direction.z(), 0.797595, 1e-5);
  // Its weight is its irradiance at the centre: 12.7324 / 1.81797^2 = 3.8525.
  EXPECT_NEAR(t[0].weight, 3.8525, 1e-3);
  // Position errors: the nearest estimated light, the worst true near light; a far one is
  // not counted.
  const Eigen::Vector3d centre(0, 0, 0.8);
  EXPECT_NEAR(WorstPositionError({{{1, 0.45, 2.0}, {1, 1, 1}, 0}, {{-1, 0, 1}, {1, 1, 1}, 0}}, t, centre, 10), 0.25,
              1e-9);
  EXPECT_TRUE(std::isinf(WorstPositionError({}, t, centre, 10)));
  EXPECT_TRUE(std::isnan(WorstPositionError({}, t, centre, 1.0)));  // the lamp is 1.82 m away: far here
}

}  // namespace
}  // namespace lp
