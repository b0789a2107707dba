// A lamp (estimation/lights/point_light.h): its forward model against closed forms, its soft
// shadow's visible share, its column's position derivative against central differences,
// and its refinement by the one light fit.
#include <cmath>

#include <gtest/gtest.h>

#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "estimation/sampling.h"
#include "scene/scene_bundle.h"
#include "tests/estimation/lights/plane_and_ball.h"
#include "tests/test_util.h"

namespace lp {
namespace {

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
    const std::vector<ImageRGB> img = RenderLights(scene, views, {PointLight{light, Eigen::Vector3d::Constant(I), 0}}, o, true);
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
  const ImageRGB img = RenderLights(scene, views, {PointLight{light, Eigen::Vector3d::Ones(), 0}}, o, true)[0];
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
    double seen = 0, single = 0, column = 0;  // kSphereShadowRays, 1 and the columns' kColumnShadowRays
    const int n = 4096;
    for (int k = 0; k < n; ++k) {
      seen += SphereVisibility(scene, p, q, r, to / d, d, k);
      single += SphereVisibility(scene, p, q, r, to / d, d, k, 1);
      column += SphereVisibility(scene, p, q, r, to / d, d, k, kColumnShadowRays);
    }
    seen /= n;
    single /= n;
    column /= n;
    std::printf("x %+.2f: seen %.4f (one ray per key %.4f, %d %.4f), the disc's segment %.4f\n", x, seen, single,
                kColumnShadowRays, column, segment(-x));
    EXPECT_NEAR(seen, segment(-x), 0.02) << x;
    EXPECT_NEAR(single, segment(-x), 0.02) << x;
    EXPECT_NEAR(column, segment(-x), 0.02) << x;
  }
  // A point light there is all or nothing.
  EXPECT_EQ(SphereVisibility(scene, {-0.05, 0, 0}, q, 0, (q - Eigen::Vector3d(-0.05, 0, 0)).normalized(),
                             (q - Eigen::Vector3d(-0.05, 0, 0)).norm(), 7),
            0.0);
}

// The column traces each vertex's shadow rays as one stream per chunk of rows
// (RayTracer::OccludedMany): it must see what SphereVisibility sees ray by ray, for a point,
// for a lamp with a size whose penumbra the ball casts on the plane, and for vertices inside
// the lamp (the ball's top within its radius: wholly lit).
TEST(PointLights, TheColumnSeesWhatEachVertexsShadowRaysSee) {
  const test::PlaneAndBall pb(24, 18, 50, 2);
  const ShadingVertices& v = pb.vertices;
  const Eigen::Vector3d top(0, 0, 0.3);  // the ball's top (centre at the origin, radius 0.3)
  for (const auto& [q, radius] : {std::pair{Eigen::Vector3d(0.4, 0.9, 1.3), 0.0},
                                  std::pair{Eigen::Vector3d(-0.2, 0.1, 1.2), 0.15},
                                  std::pair{Eigen::Vector3d(top + Eigen::Vector3d(0, 0, 0.05)), 0.2}}) {
    std::vector<float> col;
    PointLightColumn(pb.scene, v, q, &col, nullptr, radius);
    double scale = 0, shaded = 0, inside = 0;
    const double worst = test::WorstColumnDifference(v, col, [&](std::int64_t k) {
      const Eigen::Vector3d p = v.position[k].cast<double>(), n = v.normal[k].cast<double>(), to = q - p;
      const double d = to.norm();
      if (!(n.dot(to) > 0 && v.geometric[k].cast<double>().dot(to) > 0)) return Eigen::Vector3d::Zero().eval();
      const double seen = SphereVisibility(pb.scene, p, q, radius, to / d, d, static_cast<std::uint64_t>(k),
                                           kColumnShadowRays);
      shaded += seen < 1;
      inside += d <= radius;
      return Eigen::Vector3d(v.weight[k].cast<double>() * seen * n.dot(to) / (d * d * d));
    }, &scale);
    EXPECT_GT(scale, 0);
    EXPECT_LT(worst, 1e-5 * scale) << "radius " << radius << ": worst " << worst << " of " << scale;
    EXPECT_GT(shaded, 0) << radius;  // the ball shadows some vertices
    if (radius == 0.2) {
      EXPECT_GT(inside, 0);
    }
  }
}

TEST(PointLights, ThePositionDerivativeMatchesCentralDifferences) {
  const test::PlaneAndBall pb(24, 18, 50, 2);
  const RayTracer& scene = pb.scene;
  const ShadingVertices& v = pb.vertices;
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

TEST(PointLights, RefinementFindsTheLampFromHalfAMetreAway) {
  // The lamp of a plane and a ball rendered by the forward model; the refinement starts
  // 0.5 m off with the wrong intensity and must come back (positions to 1 cm).
  const test::PlaneAndBall pb(40, 30, 60, 8);
  const RayTracer& scene = pb.scene;
  const ShadingVertices& v = pb.vertices;
  const PointLight lamp{{0.5, 0.4, 1.2}, {3, 2.5, 2}, 0};
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

// ShapeDistance in CompassUnits, closed form: a lamp 2 m from the centre moved 0.2 m is
// 0.1 apart; a direction turned by 0.05 rad is 0.05 apart; two kinds are infinitely apart.
TEST(LightKinds, ShapeDistanceIsInCompassUnits) {
  const Eigen::Vector3d centre(1, 0, 0);
  PointLight was, now;
  was.position = {1, 0, 2};
  now.position = {1, 0.2, 2};
  EXPECT_NEAR(ShapeDistance(Light(now), Light(was), centre), 0.1, 1e-12);
  DirectionalLight a, b;
  a.direction = {0, 0, 1};
  b.direction = {std::sin(0.05), 0, std::cos(0.05)};
  EXPECT_NEAR(ShapeDistance(Light(b), Light(a), centre), 0.05, 1e-9);
  EXPECT_TRUE(std::isinf(ShapeDistance(Light(now), Light(a), centre)));
}

}  // namespace
}  // namespace lp
