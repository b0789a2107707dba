// The measuring functions every end-to-end, CLI and benchmark verdict rests on, against
// values computed by hand (the numbers in the comments), not against the code itself.
#include "estimation/truth.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "common/atomic_file.h"
#include "common/error.h"
#include "estimation/synth.h"

namespace lp {
namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180;

TEST(ParseTruthLights, DirectionsNormalizedWeightsFromPowerOrGiven) {
  const auto lights = ParseTruthLights(R"({"lights": [
      {"type": "sphere", "direction": [0, 0, 2], "rgb_power": [1, 2, 3]},
      {"type": "environment"},
      {"type": "sun", "direction": [3, 4, 0], "rgb": [1, 1, 1], "weight": 7}]})",
                                       "truth.json");
  ASSERT_EQ(lights.size(), 2u);  // the map without a direction is skipped
  EXPECT_EQ(lights[0].type, "sphere");
  EXPECT_NEAR((lights[0].direction - Eigen::Vector3d(0, 0, 1)).norm(), 0, 1e-15);
  EXPECT_NEAR(lights[0].weight, 0.2126 * 1 + 0.7152 * 2 + 0.0722 * 3, 1e-12);  // 1.8596, Rec. 709
  EXPECT_NEAR((lights[1].direction - Eigen::Vector3d(0.6, 0.8, 0)).norm(), 0, 1e-15);
  EXPECT_EQ(lights[1].weight, 7);  // "weight" wins over the colour
  for (const char* bad : {"", "[]", R"({"lights": 3})", R"({"lights": [{"direction": [0, 0]}]})",
                          R"({"lights": [{"direction": [0, 0, 0]}]})", R"({"lights": [{"direction": ["a", 0, 1]}]})"})
    EXPECT_THROW(ParseTruthLights(bad, "truth.json"), InputError) << bad;
}

/// A 21-ring map (up +z) lit only in the cell of world direction `d`, with `value`.
std::vector<double> OneCell(const EnvMap& env, const Eigen::Vector3d& d, double value = 1) {
  std::vector<double> lambda(3 * env.size(), 0.0);
  for (int c = 0; c < 3; ++c) lambda[3 * env.Lookup(d) + c] = value;
  return lambda;
}

// truth.json's glowing surfaces (issue 43): one quad ("corners") or several ("quads"), and
// how much of one lies on another (an intersection over union by area, in closed form).
TEST(ParseTruthEmitters, QuadsAreasAndOverlapInClosedForm) {
  const std::string text = R"({"lights": [], "emitters": [
      {"corners": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "normal": [0, 0, 1], "radiance": [2, 2, 2]},
      {"quads": [{"corners": [[0.5, 0, 0], [1.5, 0, 0], [1.5, 1, 0], [0.5, 1, 0]], "normal": [0, 0, 1]},
                 {"corners": [[5, 0, 0], [6, 0, 0], [6, 1, 0], [5, 1, 0]], "normal": [0, 0, -1]}],
       "radiance": [1, 0.5, 0.25]}]})";
  const std::vector<EmitterLight> e = ParseTruthEmitters(text, "truth.json");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_NEAR(e[0].Area(), 1.0, 1e-9);
  EXPECT_NEAR(e[1].Area(), 2.0, 1e-9);
  EXPECT_TRUE(e[1].Power().isApprox(kPi * 2.0 * Eigen::Vector3d(1, 0.5, 0.25)));
  // The first square half on the second's first quad; the second's area a quarter on the first.
  EXPECT_NEAR(AreaOn(*e[0].shape, *e[1].shape), 0.5, 0.02);
  EXPECT_NEAR(AreaOn(*e[1].shape, *e[0].shape), 0.25, 0.01);
  // A square 1.5 cm before the first, tilted so that one edge is 2.5 cm before it: on it
  // within half a cell (1 cm) nowhere; within 2 cm where its height is under 2 cm (its first
  // 5/10 of the way across), the rest off.
  const std::vector<EmitterLight> off = ParseTruthEmitters(R"({"emitters": [{"corners":
      [[0, 0, 0.015], [1, 0, 0.025], [1, 1, 0.025], [0, 1, 0.015]], "normal": [0, 0, 1], "radiance": [1, 1, 1]}]})",
                                                           "t");
  ASSERT_EQ(off.size(), 1u);
  EXPECT_NEAR(AreaOn(*off[0].shape, *e[0].shape), 0.0, 1e-9);
  EXPECT_NEAR(AreaOn(*off[0].shape, *e[0].shape, 0.02), 0.5, 0.03);
  EXPECT_NEAR(AreaOn(*off[0].shape, *e[0].shape, 0.03), 1.0, 1e-9);
  EXPECT_TRUE(ParseTruthEmitters(R"({"lights": []})", "t").empty());
  EXPECT_THROW(ParseTruthEmitters(R"({"emitters": [{"corners": [[0, 0, 0]], "normal": [0, 0, 1]}]})", "t"), InputError);
  EXPECT_THROW(ParseTruthEmitters(R"({"emitters": [{"corners": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]], "normal": [0,0,1]}]})", "t"),
               InputError);  // no radiance
}

TEST(DominantAngularErrorDeg, AgainstHandComputedCellCentres) {
  // 21 rings: the equator (ring 10) has ceil(2 pi / (pi / 20)) = 40 cells at azimuths
  // (k + 1/2) * 9 degrees from world x (frame_x for up +z). A light along +x falls in the
  // cell centred at 4.5 degrees; one lit cell is its own dominant direction.
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  const std::vector<double> lambda = OneCell(env, Eigen::Vector3d::UnitX());
  TruthLight x{"sphere", Eigen::Vector3d::UnitX(), 2, std::nullopt};
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {x}), 4.5, 1e-9);
  TruthLight at_centre{"sphere", Eigen::Vector3d(std::cos(4.5 * kDeg), std::sin(4.5 * kDeg), 0), 2, std::nullopt};
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {at_centre}), 0, 1e-6);
  // Two truth lights: the mean over both of the angle to the nearest estimate; the
  // estimate has one direction, 90 degrees from +z: (4.5 + 90) / 2.
  TruthLight z{"sphere", Eigen::Vector3d::UnitZ(), 1, std::nullopt};
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {z, x}), 47.25, 1e-9);
  // Only the two strongest count: a weaker third light far away changes nothing.
  TruthLight weak{"sphere", -Eigen::Vector3d::UnitX(), 0.1, std::nullopt};
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {weak, z, x}), 47.25, 1e-9);
  // A dark estimate is as wrong as it gets; no truth is no number.
  EXPECT_EQ(DominantAngularErrorDeg(env, std::vector<double>(3 * env.size(), 0.0), {x}), 180.0);
  EXPECT_TRUE(std::isnan(DominantAngularErrorDeg(env, lambda, {})));
  // The pole: ring 0 is one cell exactly at up.
  EXPECT_NEAR(DominantAngularErrorDeg(env, OneCell(env, Eigen::Vector3d::UnitZ()), {z}), 0, 1e-9);
}

TEST(DominantAngularErrorDeg, TheStrongestAtTheCentreWinsMapModeOrLamp) {
  // One lit cell along +x (21 rings: solid angle ~ (pi / 20) (2 pi / 40) = 0.0247 sr; radiance
  // 1: irradiance ~0.0247 at the centre) and a lamp 2 m above the centre, where the one true
  // light is. Intensity 1: 1 / 2^2 = 0.25 at the centre, the lamp is the estimate's strongest
  // (0 degrees off); intensity 0.04: 0.01, the map's mode is (90 degrees off, at the equator).
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  const std::vector<double> lambda = OneCell(env, Eigen::Vector3d::UnitX());
  const Eigen::Vector3d centre(0.5, -0.2, 0.1);
  const TruthLight z{"point", Eigen::Vector3d::UnitZ(), 1, centre + 2 * Eigen::Vector3d::UnitZ()};
  const auto lamp = [&](double I) { return PointLight{centre + 2 * Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Constant(I), 0}; };
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {lamp(1)}, centre, {z}), 0, 1e-9);
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {lamp(0.04)}, centre, {z}), 90, 1e-6);
  // A directional light counts by its irradiance: 0.1 from -x beats the cell, 0.01 does not.
  const auto sun = [](double E) {
    DirectionalLight d;
    d.direction = -Eigen::Vector3d::UnitX(), d.irradiance = Eigen::Vector3d::Constant(E);
    return d;
  };
  const TruthLight minus_x{"sun", -Eigen::Vector3d::UnitX(), 1, std::nullopt};
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {}, centre, {minus_x}, {sun(0.1)}), 0, 1e-9);
  EXPECT_NEAR(DominantAngularErrorDeg(env, lambda, {}, centre, {minus_x}, {sun(0.01)}), 175.5, 1e-6);
}

TEST(RelativeImageRmse, AgainstHandComputedValues) {
  ImageRGB ref(2, 1), img(2, 1);
  const float r[6] = {1, 1, 1, 3, 3, 3}, i[6] = {1, 1, 1, 3, 3, 5};
  for (int k = 0; k < 6; ++k) ref.data[k] = r[k], img.data[k] = i[k];
  // Squared error 4 over 6 values, reference mean 12 / 6 = 2: sqrt(4 / 6) / 2 = 0.408248.
  EXPECT_NEAR(RelativeImageRmse(img, ref, {1, 1}), std::sqrt(4.0 / 6) / 2, 1e-12);
  EXPECT_NEAR(RelativeImageRmse(img, ref, {1, 0}), 0, 1e-12);  // the differing pixel masked
  // Only pixel 1: error 4 / 3, mean 3: sqrt(4 / 3) / 3 = 0.3849.
  EXPECT_NEAR(RelativeImageRmse(img, ref, {0, 1}), std::sqrt(4.0 / 3) / 3, 1e-12);
  EXPECT_TRUE(std::isnan(RelativeImageRmse(img, ref, {0, 0})));
}

TEST(RelativeImageRmseBeyondNoise, AgainstHandComputedValues) {
  // One pixel, reference mean 2 (values 2, 2, 2). The render is 3, 2, 2: error sqrt(1 / 3) / 2,
  // squared 1 / 12. The second render 3, 2, 4 differs by (0, 0, 2): its pair's RMSE over
  // image2's mean (3) is sqrt(4 / 3) / 3, rescaled to the reference's mean (x 3 / 2) and over
  // sqrt 2: n_i^2 = (4 / 3) / 4 / 2 = 1 / 6. The second reference 2, 2, 2.6: differs by 0.6,
  // RMSE over its mean (6.6 / 3 = 2.2) sqrt(0.12) / 2.2, rescaled x 2.2 / 2 and over sqrt 2:
  // n_r^2 = 0.12 / 4 / 2 = 0.015.
  ImageRGB ref(1, 1), ref2(1, 1), img(1, 1), img2(1, 1);
  const float r[3] = {2, 2, 2}, r2[3] = {2, 2, 2.6f}, i[3] = {3, 2, 2}, i2[3] = {3, 2, 4};
  for (int k = 0; k < 3; ++k) ref.data[k] = r[k], ref2.data[k] = r2[k], img.data[k] = i[k], img2.data[k] = i2[k];
  double ni = 0, nr = 0;
  // 1 / 12 - 1 / 6 - 0.015 < 0: all of it is noise.
  EXPECT_EQ(RelativeImageRmseBeyondNoise(img, img2, ref, ref2, {1}, &ni, &nr), 0.0);
  EXPECT_NEAR(ni * ni, 1.0 / 6, 1e-6);
  EXPECT_NEAR(nr * nr, 0.015, 1e-6);
  // Noise-free renders (each pair equal): the plain error, sqrt(1 / 12).
  EXPECT_NEAR(RelativeImageRmseBeyondNoise(img, img, ref, ref, {1}), std::sqrt(1.0 / 12), 1e-7);
  // A render 5, 2, 2 (error^2 = 9 / 12 = 0.75) with the noises above: sqrt(0.75 - 1/6 - 0.015).
  ImageRGB far(1, 1), far2(1, 1);
  const float f[3] = {5, 2, 2}, f2[3] = {5, 2, 4};
  for (int k = 0; k < 3; ++k) far.data[k] = f[k], far2.data[k] = f2[k];
  // far2's mean is 11 / 3: n_i^2 = (4 / 3) / (11 / 3)^2 * (11 / 3)^2 / 4 / 2 = 1 / 6 again.
  EXPECT_NEAR(RelativeImageRmseBeyondNoise(far, far2, ref, ref2, {1}), std::sqrt(0.75 - 1.0 / 6 - 0.015), 1e-6);
  EXPECT_TRUE(std::isnan(RelativeImageRmseBeyondNoise(img, img2, ref, ref2, {0})));
}

TEST(EnvMapRelativeError, AgainstHandComputedValues) {
  // Two rings: one cell at each pole, each 2 pi steradians.
  const EnvMap env(2, Eigen::Vector3d::UnitZ());
  ASSERT_EQ(env.size(), 2);
  // sqrt(2pi * 3 * 1^2 / (2pi * 3 * 2^2)) = 0.5.
  EXPECT_NEAR(EnvMapRelativeError(env, {1, 1, 1, 0, 0, 0}, {2, 2, 2, 0, 0, 0}, {}), 0.5, 1e-12);
  // sqrt(3 * 1 / (3 * 4 + 3 * 1)) = sqrt(1 / 5).
  EXPECT_NEAR(EnvMapRelativeError(env, {1, 1, 1, 1, 1, 1}, {2, 2, 2, 1, 1, 1}, {}), std::sqrt(0.2), 1e-12);
  // The wrong cell left out: exact.
  EXPECT_NEAR(EnvMapRelativeError(env, {1, 1, 1, 1, 1, 1}, {2, 2, 2, 1, 1, 1}, {1, 0}), 0, 1e-12);
  EXPECT_TRUE(std::isnan(EnvMapRelativeError(env, {}, {}, {})));
  EXPECT_TRUE(std::isnan(EnvMapRelativeError(env, {1, 1, 1, 1, 1, 1}, {2, 2, 2, 1, 1, 1}, {1, 1})));
}

TEST(TrueCellRadiance, ASmallLightsPowerLandsInItsCell) {
  // A sphere of radius 0.1 m, 10 m away along +x, power 8 W per channel: radiance
  // P / (4 pi^2 r^2), subtending 2 pi (1 - sqrt(1 - r^2 / d^2)) sr; spread over the
  // equator cell of 21 rings: 2 pi (cos 85.5 - cos 94.5 degrees) / 40 = pi sin(4.5 deg) / 10.
  SynthLighting lighting;
  SphereLight l;
  l.position = Eigen::Vector3d(10, 0, 0);
  l.radius = 0.1;
  l.rgb_power = Eigen::Vector3d(8, 8, 8);
  lighting.lights.push_back(l);
  const EnvMap env(21, Eigen::Vector3d::UnitZ());
  const std::vector<double> cells = TrueCellRadiance(lighting, env);
  ASSERT_EQ(cells.size(), 3u * env.size());
  const double radiance = 8 / (4 * kPi * kPi * 0.01);
  const double subtended = 2 * kPi * (1 - std::sqrt(1 - 0.01 / 100));
  const double cell = kPi * std::sin(4.5 * kDeg) / 10;
  const int j = env.Lookup(Eigen::Vector3d::UnitX());
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(cells[3 * j + c], radiance * subtended / cell, 1e-9 * radiance);
  double others = 0;
  for (int k = 0; k < env.size(); ++k)
    if (k != j) others += cells[3 * k] + cells[3 * k + 1] + cells[3 * k + 2];
  EXPECT_EQ(others, 0);
  // A constant sky is that constant in every cell; a near light has no map.
  SynthLighting sky;
  sky.sky = [](const Eigen::Vector3d&) { return Eigen::Vector3d(0.5, 0.25, 2); };
  const std::vector<double> sky_cells = TrueCellRadiance(sky, env);
  for (int k = 0; k < env.size(); ++k) {
    EXPECT_NEAR(sky_cells[3 * k], 0.5, 1e-12) << k;
    EXPECT_NEAR(sky_cells[3 * k + 1], 0.25, 1e-12) << k;
    EXPECT_NEAR(sky_cells[3 * k + 2], 2, 1e-12) << k;
  }
  lighting.far = false;
  EXPECT_TRUE(TrueCellRadiance(lighting, env).empty());
}

TEST(Truth, ReadsALampGivenByItsPosition) {
  namespace fs = std::filesystem;
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
