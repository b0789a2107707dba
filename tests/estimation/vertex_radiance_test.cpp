// The viewer's lit shading (VertexRadiance) against closed forms, and RefineMesh.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "common/parallel.h"
#include "common/rng.h"
#include "estimation/path_tracer.h"
#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/render_denoise.h"
#include "estimation/truth.h"
#include "estimation/lights/light.h"
#include "estimation/vertex_radiance.h"
#include "scene/surface_filter.h"
#include "tests/test_util.h"

namespace lp {
namespace {

/// A 4 m floor of albedo 0.8 with a vertex at the origin, under a two-sided 1.2 m square
/// 0.5 m above it (albedo 0.8): most light reaching the origin has bounced.
Mesh FloorUnderASquare() {
  Mesh floor;
  floor.positions = {{0, 0, 0}, {-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}};
  floor.normals.assign(5, Eigen::Vector3f::UnitZ());
  floor.albedo.assign(5, Eigen::Vector3f::Constant(0.8f));
  floor.triangles = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}};
  floor.Append(test::Square(0, 0, 0.5, 0.6, 0.8));
  return floor;
}

/// A 9x9 camera 0.3 m above the origin looking straight down at it, and the path tracer's
/// settings that render it to compare with a vertex's radiance (3000 spp, 4 bounces).
View OriginView() { return test::BlankView(test::LookAt({0, 0, 0.3}, {0, 0, 0}, 9, 9, 2)); }
TracerOptions OriginTracer() {
  TracerOptions opt;
  opt.spp = 3000;
  opt.bounces = 4;
  opt.roulette_after = 10;
  return opt;
}
double MeanRed(const ImageRGB& image) {
  double sum = 0;
  for (std::size_t i = 0; i < image.pixels(); ++i) sum += image.data[3 * i];
  return sum / image.pixels();
}

TEST(VertexRadiance, UniformSkyOverAPlaneGivesAlbedoTimesRadiance) {
  // An open plane sees only the sky: L_o = rho/pi * (pi * L) = rho * L, per channel.
  const RayTracer scene(test::Plane(2.0, 0.6));
  const EnvMap env(11, Eigen::Vector3d::UnitZ());
  std::vector<double> lambda;
  for (int j = 0; j < env.size(); ++j) lambda.insert(lambda.end(), {1.0, 2.0, 0.5});
  // Next-event estimation (half its cells lie below the horizon) mixed with cosine sampling
  // by the power heuristic: unbiased, a few per cent of noise per vertex at 64 samples.
  VertexRadiance vr(scene, env, {lambda, {}}, 3);
  vr.Refine(64);
  ASSERT_EQ(vr.samples(), 64);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double worst = 0;
  const std::vector<Eigen::Vector3f> radiance = vr.Radiance();
  for (const Eigen::Vector3f& l : radiance) {
    const Eigen::Vector3d rel = l.cast<double>().cwiseQuotient(Eigen::Vector3d(0.6, 1.2, 0.3));
    mean += rel / radiance.size();
    worst = std::max(worst, (rel - Eigen::Vector3d::Ones()).cwiseAbs().maxCoeff());
  }
  std::printf("uniform sky, 64 samples: mean / exact %.4f %.4f %.4f over %zu vertices, worst vertex %.2f %%\n",
              mean.x(), mean.y(), mean.z(), radiance.size(), 100 * worst);
  EXPECT_LT(worst, 0.05);
  // The channels keep their ratio exactly (every sample weighs all three alike).
  for (const Eigen::Vector3f& l : radiance) EXPECT_NEAR(l.y() / l.x(), 2.0, 1e-4);
  // Unbiased: 4096 samples per vertex average to the exact value.
  vr.Refine(4096 - 64);
  mean.setZero();
  for (const Eigen::Vector3f& l : vr.Radiance()) mean += l.cast<double>() / radiance.size();
  std::printf("uniform sky, 4096 samples: mean / exact %.4f\n", mean.x() / 0.6);
  EXPECT_NEAR(mean.x() / 0.6, 1, 0.003);
}

/// A quad p0 p1 p2 p3 (counter-clockwise seen from where `normal` points) of albedo `rho`.
Mesh Quad(const Eigen::Vector3f& p0, const Eigen::Vector3f& p1, const Eigen::Vector3f& p2, const Eigen::Vector3f& p3,
          const Eigen::Vector3f& normal, float rho) {
  Mesh q;
  q.positions = {p0, p1, p2, p3};
  q.normals.assign(4, normal);
  q.albedo.assign(4, Eigen::Vector3f::Constant(rho));
  q.triangles = {{0, 1, 2}, {0, 2, 3}};
  return q;
}

/// A black 4 x 4 x 1 m room with a vertex at the middle of its floor (index 0) and a square
/// skylight of half side `c` straight above it in the ceiling.
Mesh RoomWithASkylight(float c) {
  Mesh room;
  room.positions = {{0, 0, 0}, {-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}};
  room.normals.assign(5, Eigen::Vector3f::UnitZ());
  room.albedo.assign(5, Eigen::Vector3f::Zero());
  room.triangles = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}};
  const Eigen::Vector3f down = -Eigen::Vector3f::UnitZ();
  room.Append(Quad({-2, c, 1}, {2, c, 1}, {2, 2, 1}, {-2, 2, 1}, down, 0));
  room.Append(Quad({-2, -2, 1}, {2, -2, 1}, {2, -c, 1}, {-2, -c, 1}, down, 0));
  room.Append(Quad({-2, -c, 1}, {-c, -c, 1}, {-c, c, 1}, {-2, c, 1}, down, 0));
  room.Append(Quad({c, -c, 1}, {2, -c, 1}, {2, c, 1}, {c, c, 1}, down, 0));
  room.Append(Quad({-2, -2, 0}, {-2, 2, 0}, {-2, 2, 1}, {-2, -2, 1}, Eigen::Vector3f::UnitX(), 0));
  room.Append(Quad({2, -2, 0}, {2, 2, 0}, {2, 2, 1}, {2, -2, 1}, -Eigen::Vector3f::UnitX(), 0));
  room.Append(Quad({-2, -2, 0}, {2, -2, 0}, {2, -2, 1}, {-2, -2, 1}, Eigen::Vector3f::UnitY(), 0));
  room.Append(Quad({-2, 2, 0}, {2, 2, 0}, {2, 2, 1}, {-2, 2, 1}, -Eigen::Vector3f::UnitY(), 0));
  return room;
}

TEST(VertexRadiance, TheSkyThroughASkylightIsItsViewFactorWithAndWithoutAPortal) {
  // Under a uniform sky of radiance 1 the floor's middle receives E / pi = F, the view factor
  // of the skylight (half side c, height h) from it: four corner rectangles of a = b = c / h,
  // F = 4 / (2 pi) [2 a / sqrt(1 + a^2) atan(a / sqrt(1 + a^2))].
  const double c = 0.3, a = c / 1.0, s = std::sqrt(1 + a * a);
  const double exact = 4 / (2 * M_PI) * 2 * a / s * std::atan(a / s);
  const Mesh room = RoomWithASkylight(static_cast<float>(c));
  const RayTracer scene(room);
  const EnvMap env(11, Eigen::Vector3d::UnitZ());
  const std::vector<double> lambda(3 * env.size(), 1.0);
  // The portal the skylight is, one larger than it (part of it ceiling: those next events are
  // blocked) and one smaller (the cells' strategy and cosine sampling reach the rest).
  const auto skylight = [](double half) {
    Portal p;
    p.centre = Eigen::Vector3d(0, 0, 1);
    p.half_u = p.half_v = half;
    return p;
  };
  struct Case {
    const char* name;
    std::vector<Portal> portals;
    bool stratified = false;
  };
  const std::vector<Case> cases = {{"no portal", {}},
                                   {"the skylight", {skylight(c)}},
                                   {"1.5 x larger", {skylight(1.5 * c)}},
                                   {"half as large", {skylight(0.5 * c)}},
                                   {"no portal, the first bounce stratified", {}, true}};
  constexpr int kSeeds = 24, kSamples = 640;
  std::vector<double> spread;
  for (const auto& [name, portals, stratified] : cases) {
    double sum = 0, sq = 0;
    for (int seed = 1; seed <= kSeeds; ++seed) {
      VertexRadiance vr(scene, env, {lambda, {}}, 1, seed);
      if (!portals.empty()) vr.SetPortals(portals, 0.5);
      vr.SetStratified(stratified);
      vr.Refine(kSamples);
      const double e = vr.Irradiance()[0];
      sum += e;
      sq += e * e;
    }
    const double mean = sum / kSeeds, sd = std::sqrt(std::max(0.0, sq / kSeeds - mean * mean));
    std::printf("skylight, %s: %.5f (exact %.5f), standard deviation of %d samples %.5f\n", name, mean, exact,
                kSamples, sd);
    EXPECT_NEAR(mean, exact, 4 * sd / std::sqrt(kSeeds) + 1e-4) << name;
    spread.push_back(sd);
  }
  // Half the next events aimed through the skylight: half the noise or less (0.0047 against
  // 0.0093 when written; 0.0137 against 0.0384 at 64 samples, where a miss-or-hit estimate's
  // spread over 24 seeds is itself noisy); a portal larger than the skylight wastes some.
  EXPECT_LT(spread[1], spread[0] / 1.6);
  EXPECT_LT(spread[2], spread[0] / 1.2);
  // The cosine-sampled directions from a Sobol sequence: as unbiased (above), less spread.
  EXPECT_LT(spread[4], spread[0] / 1.2);
}

TEST(VertexRadiance, OneLitCellMatchesTheIrradianceOfASmallSource) {
  // One cell of radiance L at polar angle theta: E ~ L * Omega * cos(theta), L_o = rho/pi * E.
  const RayTracer scene(test::Plane(2.0, 0.5));
  const EnvMap env(11, Eigen::Vector3d::UnitZ());
  const int j = env.size() / 4;  // a cell in the upper hemisphere
  ASSERT_GT(env.direction(j).z(), 0.3);
  std::vector<double> lambda(3 * env.size(), 0.0);
  for (int c = 0; c < 3; ++c) lambda[3 * j + c] = 10.0;
  VertexRadiance vr(scene, env, {lambda, {}}, 1, 7);
  vr.Refine(400);
  // The cell's cosine varies across it: integrate it finely for the reference.
  double cos_integral = 0;
  const int n = 200;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) cos_integral += env.SampleInCell(j, (a + 0.5) / n, (b + 0.5) / n).z();
  cos_integral *= env.solid_angle(j) / (n * n);
  const double expected = 0.5 / M_PI * 10.0 * cos_integral;
  // Next-event estimation draws the lit cell 95 % of the time: 400 samples are within 3 %
  // (cosine sampling alone needed 40,000 for that: the cell has probability ~0.03).
  double worst = 0;
  for (const Eigen::Vector3f& l : vr.Radiance()) worst = std::max(worst, std::abs(l.x() / expected - 1));
  std::printf("one lit cell, 400 samples: worst vertex %.2f %% off\n", 100 * worst);
  EXPECT_LT(worst, 0.03);
}

TEST(VertexRadiance, InterreflectionsAgreeWithThePathTracer) {
  // A floor (a vertex at the origin) under a two-sided square that hides most of its sky:
  // light reaches the origin mostly after bouncing between the square and the floor. The
  // path tracer renders the origin through a camera looking straight down at it; a
  // Lambertian surface sends the same radiance every way, so the two must agree.
  const RayTracer scene(FloorUnderASquare());
  const EnvMap env(9, Eigen::Vector3d::UnitZ());
  const std::vector<double> lambda(3 * env.size(), 1.0);
  VertexRadiance vr(scene, env, {lambda, {}}, 4, 3);
  vr.Refine(20000);
  const double vertex = vr.Radiance()[0].x();

  const double pixel = MeanRed(RenderEnvironment(scene, env, {OriginView()}, lambda, CellSampler(env, lambda, {}, 0.2),
                                                 OriginTracer(), true)[0]);
  std::printf("origin under the square: vertex radiance %.4f, path tracer %.4f\n", vertex, pixel);
  EXPECT_NEAR(vertex, pixel, 0.04 * pixel) << "vertex " << vertex << ", path tracer " << pixel;
  VertexRadiance stratified(scene, env, {lambda, {}}, 4, 3);  // (its first bounce from a Sobol sequence)
  stratified.SetStratified(true);
  stratified.Refine(20000);
  std::printf("the first bounce stratified: %.4f\n", stratified.Radiance()[0].x());
  EXPECT_NEAR(stratified.Radiance()[0].x(), pixel, 0.04 * pixel);
  VertexRadiance direct(scene, env, {lambda, {}}, 1, 3);
  direct.Refine(20000);
  std::printf("direct light only: %.4f\n", direct.Radiance()[0].x());
  EXPECT_LT(direct.Radiance()[0].x(), 0.85 * vertex) << "the bounces carry a visible share";
}

TEST(VertexRadiance, PointLightOverAPlaneIsTheInverseSquareLaw) {
  // Direct light only, the map dark: L_o = rho/pi * I cos(theta) / d^2 at every vertex, exactly
  // (a point light is one shadow ray: no noise).
  const double rho = 0.5;
  const RayTracer scene(test::Plane(2.0, rho));
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  PointLight lamp;
  lamp.position = {0.3, -0.2, 0.8};
  lamp.intensity = {2.0, 1.0, 0.5};
  VertexRadiance vr(scene, env, {std::vector<double>(3 * env.size(), 0.0), {lamp}}, 1, 1);
  vr.Refine(2);
  const std::vector<Eigen::Vector3f> radiance = vr.Radiance();
  const Mesh& mesh = scene.mesh();
  double worst = 0;
  for (std::size_t v = 0; v < radiance.size(); ++v) {
    const Eigen::Vector3d r = lamp.position - mesh.positions[v].cast<double>();
    const double d = r.norm(), expected = rho / M_PI * lamp.intensity.x() * (r.z() / d) / (d * d);
    worst = std::max(worst, std::abs(radiance[v].x() / expected - 1));
    EXPECT_NEAR(radiance[v].y() / radiance[v].x(), 0.5, 1e-5);
  }
  std::printf("point light over a plane: worst vertex %.4f %% off I cos/d^2\n", 100 * worst);
  EXPECT_LT(worst, 1e-3);  // the vertex is shaded 4 epsilon off the surface
}

TEST(VertexRadiance, PointLightInterreflectionsAgreeWithThePathTracer) {
  // The floor and square of the test above, lit by a lamp between them off to the side: the
  // origin sees the lamp directly and again off the square's underside. Vertex radiance
  // (4 bounces) against the point-light path tracer through a camera looking down at it.
  const RayTracer scene(FloorUnderASquare());
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  PointLight lamp;
  lamp.position = {0.9, 0.1, 0.3};
  lamp.intensity = {1.0, 1.0, 1.0};
  VertexRadiance vr(scene, env, {std::vector<double>(3 * env.size(), 0.0), {lamp}}, 4, 3);
  vr.Refine(20000);
  const double vertex = vr.Radiance()[0].x();

  const double pixel = MeanRed(RenderLights(scene, {OriginView()}, {lamp}, OriginTracer(), true)[0]);
  const Eigen::Vector3d r = lamp.position;
  const double direct = 0.8 / M_PI * r.z() / r.norm() / r.squaredNorm();
  std::printf("origin under the square, lamp beside: vertex %.4f, path tracer %.4f, direct alone %.4f\n", vertex,
              pixel, direct);
  EXPECT_NEAR(vertex, pixel, 0.03 * pixel);
  EXPECT_GT(vertex, 1.1 * direct) << "the bounces carry a visible share";
}

TEST(VertexRadiance, RefiningAddsSamplesAndStaysConsistent) {
  const RayTracer scene(test::Ball(1.0, 0.5, 8, 16));
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  std::vector<double> lambda(3 * env.size(), 1.0);
  VertexRadiance vr(scene, env, {lambda, {}}, 2), once(scene, env, {lambda, {}}, 2);
  vr.Refine(48);
  vr.Refine(16);
  once.Refine(64);
  EXPECT_EQ(vr.samples(), 64);
  // Samples are numbered: 48 + 16 are the 64 of one call, bit for bit.
  EXPECT_EQ(vr.Radiance(), once.Radiance());
  // A convex ball under a uniform sky: every vertex sees only the sky, L_o = rho * L
  // (64 samples: ~4 % noise per vertex; next-event estimation spends half its samples
  // below each vertex's horizon here, where cosine sampling alone had none).
  double mean = 0;
  const std::vector<Eigen::Vector3f> radiance = vr.Radiance();
  for (const Eigen::Vector3f& l : radiance) {
    EXPECT_NEAR(l.x(), 0.5, 0.1);
    mean += l.x() / radiance.size();
  }
  EXPECT_NEAR(mean, 0.5, 0.01);
}

TEST(VertexRadiance, RefiningSomeVerticesContinuesTheirOwnPaths) {
  // The albedo pass gives some vertices more paths than others: a vertex refined 16 + 16
  // paths has exactly the radiance of 32 in one call, and one left out keeps its 16.
  const RayTracer scene(test::Ball(1.0, 0.5, 8, 16));
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  const std::vector<double> lambda(3 * env.size(), 1.0);
  VertexRadiance some(scene, env, {lambda, {}}, 2), all16(scene, env, {lambda, {}}, 2), all32(scene, env, {lambda, {}}, 2);
  const std::size_t n = scene.mesh().positions.size();
  std::vector<std::uint8_t> odd(n, 0);
  for (std::size_t v = 1; v < n; v += 2) odd[v] = 1;
  some.Refine(16);
  some.Refine(16, odd);
  all16.Refine(16);
  all32.Refine(32);
  const std::vector<float> e = some.Irradiance(), e16 = all16.Irradiance(), e32 = all32.Irradiance();
  for (std::size_t v = 0; v < n; ++v) {
    EXPECT_EQ(some.samples(v), odd[v] ? 32 : 16);
    EXPECT_EQ(e[v], odd[v] ? e32[v] : e16[v]) << "vertex " << v;
  }
  EXPECT_EQ(some.samples(), -1) << "no longer one count for all";
  std::vector<std::uint8_t> short_mask(n - 1, 1);
  EXPECT_THROW(some.Refine(2, short_mask), std::exception);
}

TEST(VertexRadiance, TheIrradiancesVarianceIsItsSpreadOverSeeds) {
  // A floor under a square that hides most of its sky (light mostly after bounces: a
  // skewed, wide distribution of path values): the variance each vertex says its mean has,
  // from its own 8 paths, averaged over 400 seeds, against the variance of that mean over
  // the seeds. Divided by the paths once too often (or not at all) it is off 8 times.
  const RayTracer scene(FloorUnderASquare());
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  const std::vector<double> lambda(3 * env.size(), 1.0);
  const int seeds = 400;
  std::vector<double> sum(5, 0), sum2(5, 0), said(5, 0);
  for (int seed = 1; seed <= seeds; ++seed) {
    VertexRadiance vr(scene, env, {lambda, {}}, 3, seed);
    vr.Refine(8);
    const std::vector<float> e = vr.Irradiance(), var = vr.IrradianceVariance();
    for (int v = 0; v < 5; ++v) {  // the floor's vertices (the origin under the square, the corners)
      sum[v] += e[v];
      sum2[v] += static_cast<double>(e[v]) * e[v];
      said[v] += var[v] / seeds;
    }
  }
  for (int v = 0; v < 5; ++v) {
    const double mean = sum[v] / seeds, spread = (sum2[v] - seeds * mean * mean) / (seeds - 1);
    std::printf("vertex %d: irradiance %.4f, its variance over seeds %.3g, said %.3g (ratio %.3f)\n", v, mean, spread,
                said[v], said[v] / spread);
    // The spread's own sampling error over 400 seeds is about 7 % (more for skewed paths).
    EXPECT_NEAR(said[v] / spread, 1.0, 0.25) << "vertex " << v;
  }
}

TEST(VertexRadiance, TheCleanLitShadingIsWithinTheNoiseItSays) {
  // A floor under a uniform sky (radiance 1: its part of the incident radiance is 1 at
  // every vertex, sampled with noise) and a lamp (I cos / (pi d^2), exact: one shadow ray).
  // The clean shading's error against that closed form is what it says its noise is, and
  // far below the raw per-vertex average's.
  const double rho = 0.5;
  const RayTracer scene(test::FineFloor(rho));
  const EnvMap env(11, Eigen::Vector3d::UnitZ());
  PointLight lamp;
  lamp.position = {0.2, -0.1, 0.6};
  lamp.intensity = Eigen::Vector3d::Constant(1.5);
  VertexRadiance vr(scene, env, {std::vector<double>(3 * env.size(), 1.0), {lamp}}, 1, 3);
  const Mesh& mesh = scene.mesh();
  const auto relative_rms = [&](const std::vector<Eigen::Vector3f>& radiance) {
    double e2 = 0;
    for (std::size_t v = 0; v < radiance.size(); ++v) {
      const Eigen::Vector3d r = lamp.position - mesh.positions[v].cast<double>();
      const double d = r.norm();
      const double exact = rho * (1 + lamp.intensity.x() * (r.z() / d) / (M_PI * d * d));
      e2 += std::pow(radiance[v].y() / exact - 1, 2);
    }
    return std::sqrt(e2 / radiance.size());
  };
  const SurfaceFilter filter;  // 1 cm, 8 steps: the mesh's own spacing
  double said = 1;
  for (int samples = 4; samples <= 64; samples *= 4) {
    vr.Refine(samples - vr.samples());
    const LitShading clean = vr.Clean(filter);
    const double raw = relative_rms(vr.Radiance()), got = relative_rms(clean.radiance);
    std::printf("%2d samples: raw %.2f %%, clean %.2f %% (says %.2f %%)\n", samples, 100 * raw, 100 * got,
                100 * clean.noise);
    EXPECT_LT(got, raw / 3) << samples;
    // Honest: the error is the noise it says (the lamp's fall-off is smooth over the blur).
    EXPECT_GT(clean.noise, got / 1.5) << samples;
    EXPECT_LT(clean.noise, got * 1.5) << samples;
    EXPECT_LT(clean.noise, said) << samples;
    said = clean.noise;
  }
  EXPECT_LT(said, 0.01);
}

TEST(VertexRadiance, TheCleanShadingKeepsALampsLightAtEachVertexAsTraced) {
  // A floor whose normals are tilted by up to 10 degrees from vertex to vertex (a scan's),
  // 30 cm under a lamp, the map dark, direct light only: each vertex's radiance is
  // rho/pi I cos/d^2 with its own normal, and a point light's is the same in every sample.
  // Clean takes it as traced (smoothing it would mix the light of neighbours' normals: that
  // made the demo's lit mesh 6 % off a reference) and says no noise.
  const double rho = 0.5;
  const RayTracer scene(test::FineFloor(rho, 10 * M_PI / 180));
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  PointLight lamp;
  lamp.position = {0.1, 0.05, 0.3};
  lamp.intensity = Eigen::Vector3d::Constant(0.2);
  VertexRadiance vr(scene, env, {std::vector<double>(3 * env.size(), 0.0), {lamp}}, 1, 1);
  vr.Refine(4);
  const Mesh& mesh = scene.mesh();
  const auto relative_rms = [&](const std::vector<Eigen::Vector3f>& radiance, double* worst) {
    double e2 = 0;
    for (std::size_t v = 0; v < radiance.size(); ++v) {
      const Eigen::Vector3d r = lamp.position - mesh.positions[v].cast<double>();
      const double d = r.norm(), cosine = mesh.normals[v].cast<double>().dot(r) / d;
      const double e = radiance[v].x() / (rho / M_PI * lamp.intensity.x() * cosine / (d * d)) - 1;
      e2 += e * e;
      *worst = std::max(*worst, std::abs(e));
    }
    return std::sqrt(e2 / radiance.size());
  };
  const LitShading clean = vr.Clean(SurfaceFilter{});
  double worst = 0, worst_smoothed = 0;
  const double rms = relative_rms(clean.radiance, &worst);
  const double smoothed = relative_rms(SmoothOverSurface(mesh, vr.Radiance()), &worst_smoothed);
  std::printf("a lamp over tilted normals: clean %.4f %% RMS (worst %.4f %%), the radiance smoothed %.2f %% (worst %.2f "
              "%%), noise said %g\n",
              100 * rms, 100 * worst, 100 * smoothed, 100 * worst_smoothed, clean.noise);
  EXPECT_LT(worst, 1e-3);
  EXPECT_GT(smoothed, 0.01);  // what the test tells apart
  EXPECT_EQ(clean.noise, 0);
}

TEST(ProgressiveRender, StopsAtTheNoiseItWasAskedAndSaysItsNoiseHonestly) {
  // The floor under a square, a lamp beside them and a uniform sky (interreflections: noisy)
  // seen by a 24x24 camera. Passes double the samples (8 a half, then 16, 32, ...: 16, 48,
  // 112 in all) while the noise asked is far, and the last is what reaches it with a tenth
  // to spare (the noise as one over the root of the samples): fewer than doubling, and the
  // noise falls each pass; it stops at the first pass under the noise asked; the
  // noise it reports is the RMS of the render against an independent one at the same samples
  // over sqrt 2 (their difference holds both noises), within 25 %; no light: no noise, one
  // pass; the samples never exceed the most asked.
  const RayTracer scene(FloorUnderASquare());
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  const Lighting lighting{std::vector<double>(3 * env.size(), 0.2), {PointLight{{0.9, 0.3, 0.35}, {1.0, 0.8, 0.6}, 0}}};
  const CellSampler sampler(env, lighting.map, {}, 0.2);
  const std::vector<View> views{test::BlankView(test::LookAt({0.2, -0.9, 0.6}, {0, 0, 0}, 24, 24, 20))};
  TracerOptions t;
  t.spp = 8;
  t.bounces = 4;
  std::vector<RenderPass> passes;
  const std::vector<ImageRGB> a = ProgressiveRender(scene, env, lighting, sampler, views, t, 0.02, 1e9, 1 << 20, &passes);
  ASSERT_GE(passes.size(), 2u);
  for (std::size_t k = 0; k + 1 < passes.size(); ++k) EXPECT_EQ(passes[k].spp, 16 * ((1 << (k + 1)) - 1)) << k;
  const int before = passes[passes.size() - 2].spp;
  EXPECT_GT(passes.back().spp, before);
  EXPECT_LT(passes.back().spp, 3 * before + 16);  // (doubling: 2 x before + 16)
  for (std::size_t k = 1; k < passes.size(); ++k) EXPECT_LT(passes[k].noise, passes[k - 1].noise) << k;
  EXPECT_LE(passes.back().noise, 0.02);
  EXPECT_GT(passes[passes.size() - 2].noise, 0.02);
  t.seed = 99;
  std::vector<RenderPass> other_passes;
  const std::vector<ImageRGB> b = ProgressiveRender(scene, env, lighting, sampler, views, t, 0.02, 1e9, 1 << 20, &other_passes);
  EXPECT_NEAR(other_passes.back().spp, passes.back().spp, 0.15 * passes.back().spp);  // (its last pass its own)
  double d2 = 0, sum = 0;
  for (std::size_t i = 0; i < a[0].data.size(); ++i) {
    d2 += (a[0].data[i] - b[0].data[i]) * (a[0].data[i] - b[0].data[i]);
    sum += 0.5 * (a[0].data[i] + b[0].data[i]);
  }
  const double measured = std::sqrt(d2 / a[0].data.size()) / (sum / a[0].data.size()) / std::sqrt(2.0);
  std::printf("%zu passes, %d samples: noise said %.4f and %.4f, measured %.4f\n", passes.size(), passes.back().spp,
              passes.back().noise, other_passes.back().noise, measured);
  EXPECT_NEAR(measured, passes.back().noise, 0.25 * passes.back().noise);
  // At most 100 samples: 16 and 48; the next pass would make 112.
  ProgressiveRender(scene, env, lighting, sampler, views, t, 0, 1e9, 100, &passes);
  ASSERT_EQ(passes.size(), 2u);
  EXPECT_EQ(passes.back().spp, 48);
  // No light: nothing to be noisy, one pass.
  ProgressiveRender(scene, env, {std::vector<double>(3 * env.size(), 0.0), {}}, sampler, views, t, 0.02, 1e9, 1 << 20,
                    &passes);
  ASSERT_EQ(passes.size(), 1u);
  EXPECT_EQ(passes[0].noise, 0);
}

TEST(ProgressiveRender, DenoisedItKeepsTheTextureAndSaysItsNoiseHonestly) {
  // A checkered floor (albedo 0.15 and 0.8 in 5 cm squares, a vertex a centimetre) under a
  // sky and a lamp, seen from above by a 64x48 camera. Denoised, the render at 96 samples a
  // pixel is closer to a 3072-sample reference (its own noise taken out) than the plain one
  // by 2.5x or more; the error is the noise it says (the blur's bias small); the dark squares
  // keep their level (texture is not smoothed: its mean ratio to the reference within 2 %).
  Mesh floor = test::FineFloor(0.8);
  for (std::size_t v = 0; v < floor.positions.size(); ++v) {
    const int cx = static_cast<int>(std::floor((floor.positions[v].x() + 0.5) / 0.05));
    const int cy = static_cast<int>(std::floor((floor.positions[v].y() + 0.5) / 0.05));
    if ((cx + cy) % 2) floor.albedo[v] = Eigen::Vector3f::Constant(0.15f);
  }
  const RayTracer scene(floor);
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  const Lighting lighting{std::vector<double>(3 * env.size(), 0.3), {PointLight{{0.2, -0.1, 0.6}, {1.0, 1.0, 1.0}, 0}}};
  const CellSampler sampler(env, lighting.map, {}, 0.2);
  const std::vector<View> views{test::BlankView(test::LookAt({0.05, 0.02, 0.9}, {0, 0, 0}, 64, 48, 50))};
  TracerOptions t;
  t.spp = 16;
  t.bounces = 2;
  std::vector<RenderPass> plain_passes, denoised_passes, ref_passes;
  const ImageRGB plain = ProgressiveRender(scene, env, lighting, sampler, views, t, 0, 1e9, 96, &plain_passes)[0];
  const ImageRGB denoised =
      ProgressiveRender(scene, env, lighting, sampler, views, t, 0, 1e9, 96, &denoised_passes, {}, true)[0];
  t.seed = 5;
  t.spp = 512;
  const ImageRGB reference = ProgressiveRender(scene, env, lighting, sampler, views, t, 0, 1e9, 4096, &ref_passes)[0];
  ASSERT_EQ(plain_passes.back().spp, 96);  // 2 x (16 + 32)
  ASSERT_EQ(ref_passes.back().spp, 3072);
  const std::vector<std::uint8_t> all(plain.pixels(), 1);
  const double ref_noise = ref_passes.back().noise;
  const auto beyond = [&](const ImageRGB& im) {
    const double e = RelativeImageRmse(im, reference, all);
    return std::sqrt(std::max(0.0, e * e - ref_noise * ref_noise));
  };
  const double plain_error = beyond(plain), denoised_error = beyond(denoised);
  double dark_ratio = 0;
  int dark = 0;
  const PixelGuide guide = GuideOf(scene, views[0].camera, {});
  for (std::size_t i = 0; i < plain.pixels(); ++i)
    if (guide.albedo[i].x() < 0.2f) {
      dark_ratio += denoised.data[3 * i] / reference.data[3 * i];
      ++dark;
    }
  dark_ratio /= dark;
  std::printf("96 samples: plain %.2f %% (says %.2f %%), denoised %.2f %% (says %.2f %%); reference noise %.2f %%; "
              "dark squares' level %.4f of the reference's over %d pixels\n",
              100 * plain_error, 100 * plain_passes.back().noise, 100 * denoised_error,
              100 * denoised_passes.back().noise, 100 * ref_noise, dark_ratio, dark);
  EXPECT_LT(denoised_error, plain_error / 2.5);
  EXPECT_GT(denoised_error, denoised_passes.back().noise / 1.5);
  EXPECT_LT(denoised_error, denoised_passes.back().noise * 1.5);
  EXPECT_GT(dark, 200);
  EXPECT_NEAR(dark_ratio, 1, 0.02);
}

TEST(VertexPhotometricError, ComparesWithTheNearestViewThatSeesTheVertex) {
  // A plane seen from above by a near view (image 0.2) and a far one (image 0.9); a
  // vertex under an occluding square is seen by neither.
  Mesh mesh = RefineMesh(test::Plane(2.0, 0.5), 64);
  const RayTracer scene(mesh);
  const std::vector<Eigen::Vector3f> radiance(scene.mesh().positions.size(), Eigen::Vector3f::Constant(0.5f));
  View near_view = test::BlankView(test::LookAt({0, 0, 2}, {0, 0, 0}, 64, 48, 90));
  View far_view = test::BlankView(test::LookAt({0, 0, 4}, {0, 0, 0}, 64, 48, 90));
  std::fill(near_view.image.data.begin(), near_view.image.data.end(), 0.2f);
  std::fill(far_view.image.data.begin(), far_view.image.data.end(), 0.9f);
  const std::vector<float> err = VertexPhotometricError(scene, {far_view, near_view}, radiance);
  int seen = 0;
  for (std::size_t v = 0; v < err.size(); ++v) {
    if (std::isnan(err[v])) continue;
    ++seen;
    // The near view sees the centre of the plane: |0.5 - 0.2| over its white level 0.2.
    if (scene.mesh().positions[v].norm() < 0.5f) {
      EXPECT_NEAR(err[v], 1.5, 1e-5);
    }
  }
  EXPECT_GT(seen, 10);

  Mesh occluded = test::Plane(2.0, 0.5);
  occluded.Append(test::Square(0, 0, 1.0, 1.5, 0.5));  // covers the whole plane
  const RayTracer blocked(occluded);
  const std::vector<Eigen::Vector3f> rad2(blocked.mesh().positions.size(), Eigen::Vector3f::Constant(0.5f));
  const std::vector<float> err2 = VertexPhotometricError(blocked, {near_view}, rad2);
  for (int v = 0; v < 4; ++v) EXPECT_TRUE(std::isnan(err2[v])) << "vertex " << v << " is under the square";
}

TEST(RefineMesh, ReachesTheTriangleCountAndKeepsTheSurface) {
  const Mesh plane = test::Plane(2.0, 0.5);
  const Mesh fine = RefineMesh(plane, 1000);
  EXPECT_GE(fine.triangles.size(), 1000u);
  EXPECT_LT(fine.triangles.size(), 1010u);
  double area = 0;
  for (const auto& t : fine.triangles) {
    const Eigen::Vector3f n =
        (fine.positions[t[1]] - fine.positions[t[0]]).cross(fine.positions[t[2]] - fine.positions[t[0]]);
    EXPECT_GT(n.z(), 0) << "winding kept";
    area += 0.5 * n.norm();
  }
  EXPECT_NEAR(area, 4.0, 1e-4);
  ASSERT_EQ(fine.normals.size(), fine.positions.size());
  ASSERT_EQ(fine.albedo.size(), fine.positions.size());
  for (const auto& p : fine.positions) EXPECT_EQ(p.z(), 0.f);
}

TEST(SanitizeMesh, OneUnusableNormalDoesNotDiscardTheOthers) {
  // Smoothed (tilted) normals from a file, and one zero normal: only that one is recomputed.
  Mesh m = test::Plane(1.0, 0.5);
  const Eigen::Vector3f tilted = Eigen::Vector3f(0.3f, 0, 1).normalized();
  m.normals = {tilted, tilted, 2 * tilted, Eigen::Vector3f::Zero()};
  SanitizeMesh(&m, "test");
  for (int v = 0; v < 3; ++v) EXPECT_TRUE(m.normals[v].isApprox(tilted, 1e-6f)) << v;
  EXPECT_TRUE(m.normals[3].isApprox(Eigen::Vector3f::UnitZ(), 1e-6f));
}

// Depth noise a voxel across, as fusion leaves it: Taubin smoothing straightens the normals
// of a noisy plane and keeps a noisy sphere's radius, where plain Laplacian smoothing
// (mu = 0) of the same strength shrinks it.
TEST(SmoothMesh, StraightensNoisyNormalsWithoutShrinking) {
  Rng rng(3);
  const auto noise = [&rng](double sd) { return sd * std::sqrt(12.0) * (rng.Uniform() - 0.5); };  // uniform, sd
  Mesh plane;
  const int n = 101;  // 1 m, 1 cm apart
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      plane.positions.emplace_back(0.01f * j, 0.01f * i, static_cast<float>(noise(0.006)));
      plane.albedo.emplace_back(0.5f, 0.5f, 0.5f);
    }
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j;
      plane.triangles.emplace_back(a, a + 1, a + n + 1);
      plane.triangles.emplace_back(a, a + n + 1, a + n);
    }
  const auto mean_nz = [](const Mesh& m) {
    double s = 0;
    for (const auto& v : m.normals) s += std::abs(v.z());
    return s / m.normals.size();
  };
  ComputeVertexNormals(&plane);
  const double before = mean_nz(plane);
  SmoothMesh(&plane, 40);
  const double after = mean_nz(plane);
  std::printf("plane: mean |n.z| %.3f -> %.3f\n", before, after);
  EXPECT_LT(before, 0.92);
  EXPECT_GT(after, 0.99);

  Mesh sphere = UvSphere(Eigen::Vector3f::Zero(), 0.35f, Eigen::Vector3f::Constant(0.5f), 48, 96);
  for (auto& p : sphere.positions) p *= static_cast<float>(1 + noise(0.006));
  const auto mean_radius = [](const Mesh& m) {
    double s = 0;
    for (const auto& p : m.positions) s += p.norm();
    return s / m.positions.size();
  };
  Mesh laplacian = sphere;
  SmoothMesh(&sphere, 40);
  SmoothMesh(&laplacian, 40, 0.5f, 0.f);
  std::printf("sphere radius 0.35: Taubin %.4f, Laplacian %.4f\n", mean_radius(sphere), mean_radius(laplacian));
  EXPECT_NEAR(mean_radius(sphere), 0.35, 0.002);
  EXPECT_LT(mean_radius(laplacian), 0.35 - 0.004);
}

// One step in closed form: a flat grid's centre lifted by h, one Laplacian step of weight
// lambda (mu = 0: the second step does nothing) moves it to h (1 - lambda) and each of its
// neighbours (the other corners of its triangles, each counted once) to lambda h / degree;
// the same bits on one thread as on two (each vertex from the positions before the step).
TEST(SmoothMesh, OneStepIsTheNeighboursMeanAndTheSameOnAnyThreadCount) {
  const int n = 65;
  Mesh grid;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) grid.positions.emplace_back(0.01f * j, 0.01f * i, 0.f);
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j;
      grid.triangles.emplace_back(a, a + 1, a + n + 1);
      grid.triangles.emplace_back(a, a + n + 1, a + n);
    }
  const int centre = (n / 2) * n + n / 2;
  const float h = 0.1f, lambda = 0.5f;
  grid.positions[centre].z() = h;
  Mesh one = grid;
  SmoothMesh(&one, 1, lambda, 0.f);
  EXPECT_NEAR(one.positions[centre].z(), h * (1 - lambda), 1e-7);
  // On this grid an interior vertex has 6 neighbours: right, left, up, down and two diagonals.
  for (const int d : {1, -1, n, -n, n + 1, -n - 1})
    EXPECT_NEAR(one.positions[centre + d].z(), lambda * h / 6, 1e-7) << d;
  EXPECT_EQ(one.positions[centre + n - 1].z(), 0.f);  // not a neighbour (the other diagonal)

  Mesh serial = grid, parallel = grid;
  Rng rng(5);
  for (std::size_t k = 0; k < grid.positions.size(); ++k)
    serial.positions[k].z() = parallel.positions[k].z() = static_cast<float>(0.01 * (rng.Uniform() - 0.5));
  {
    ThreadLimit limit(1);
    SmoothMesh(&serial, 40);
  }
  {
    ThreadLimit limit(2);
    SmoothMesh(&parallel, 40);
  }
  for (std::size_t k = 0; k < grid.positions.size(); ++k) ASSERT_EQ(serial.positions[k], parallel.positions[k]) << k;
}

}  // namespace
}  // namespace lp
