// lights.json (estimation/lights_file.h): every kind of light written and read back, and bad
// lights refused with a clear error.
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/error.h"
#include "estimation/lights_file.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

TEST(LightsFile, RoundTripsAndRefusesBadLights) {
  const LightsFile in{"envmap.exr", {PointLight{{1, 2, 3}, {0.5, 0.25, 0}, 0.05}}, {}, {}};
  const LightsFile out = ParseLightsJson(LightsJson(in), "lights.json");
  EXPECT_EQ(out.environment, "envmap.exr");
  const std::vector<PointLight> lamps = OfKind<PointLight>(out.lights);
  ASSERT_EQ(out.lights.size(), 1u);
  ASSERT_EQ(lamps.size(), 1u);
  EXPECT_EQ(lamps[0].position, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(lamps[0].intensity, Eigen::Vector3d(0.5, 0.25, 0));
  EXPECT_EQ(lamps[0].radius, 0.05);
  EXPECT_FALSE(lamps[0].held);
  EXPECT_EQ(LightsJson(in).find("held"), std::string::npos);  // (written only where held)
  PointLight seen{{1, 2, 3}, {1, 1, 1}, 0};
  seen.held = true;
  EXPECT_TRUE(OfKind<PointLight>(ParseLightsJson(LightsJson({"", {seen}, {}, {}}), "x").lights).at(0).held);
  EXPECT_THROW(ParseLightsJson(R"({"point_lights": [{"position": [0, 0, 0], "intensity": [1, 1, 1], "held": 1}]})", "x"),
               InputError);
  EXPECT_NE(LightsJson(in).find("\"directional_lights\": []"), std::string::npos);  // always present
  // Directional lights: the direction is normalized, the rest kept.
  LightsFile sun;
  sun.lights.push_back(DirectionalLight{{0, 3, 4}, {2, 1.5, 1}, 0.0046});
  const LightsFile back = ParseLightsJson(LightsJson(sun), "lights.json");
  ASSERT_EQ(back.lights.size(), 1u);
  const DirectionalLight d = OfKind<DirectionalLight>(back.lights).at(0);
  EXPECT_TRUE(d.direction.isApprox(Eigen::Vector3d(0, 0.6, 0.8), 1e-15));
  EXPECT_EQ(d.irradiance, Eigen::Vector3d(2, 1.5, 1));
  EXPECT_EQ(d.angular_radius, 0.0046);
  // Both kinds in one file come back, each under its key.
  const LightsFile both{"", {DirectionalLight{{0, 0, 1}, {1, 1, 1}, 0}, PointLight{{0, 0, 2}, {3, 3, 3}, 0}}, {}, {}};
  const LightsFile both_back = ParseLightsJson(LightsJson(both), "lights.json");
  EXPECT_EQ(OfKind<PointLight>(both_back.lights).size(), 1u);
  EXPECT_EQ(OfKind<DirectionalLight>(both_back.lights).size(), 1u);
  // Unknown keys are ignored; no environment and no lights is an empty lighting, and a file
  // from before directional lights has none.
  const LightsFile empty = ParseLightsJson(R"({"point_lights": [], "directional_lights": [], "x": 1})", "x");
  EXPECT_TRUE(empty.environment.empty());
  EXPECT_TRUE(empty.lights.empty());
  EXPECT_TRUE(ParseLightsJson(R"({"point_lights": []})", "x").lights.empty());
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

TEST(LightsFile, EachLightsUncertaintyRoundTripsUnknownAsNull) {
  // Each light keeps its own uncertainty through the file, kind by kind; an entry the data
  // do not fix is written as null and read back as infinite; a light without the keys gets
  // "unknown"; malformed entries are one-line errors.
  LightUncertainty lamp, sun;
  lamp.shape_covariance << 4e-4, 1e-4, 0, 1e-4, 9e-4, 2e-5, 0, 2e-5, 1e-2;
  lamp.scale_sigma = {0.1, 0.2, 0.3};
  sun.shape_covariance = Eigen::Vector3d(1e-6, 4e-6, 0).asDiagonal();
  sun.scale_sigma = {0.01, INFINITY, 0.03};
  const LightsFile in{"", {DirectionalLight{{0, 0, 1}, {1, 1, 1}, 0}, PointLight{{0, 0, 2}, {3, 3, 3}, 0}}, {sun, lamp}, {}};
  const std::string text = LightsJson(in);
  EXPECT_NE(text.find("\"position_covariance\""), std::string::npos);
  EXPECT_NE(text.find("\"direction_covariance\""), std::string::npos);
  EXPECT_NE(text.find("null"), std::string::npos);
  const LightsFile out = ParseLightsJson(text, "lights.json");
  ASSERT_EQ(out.uncertainty.size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {  // each with its light, in the file's order of kinds
    const LightUncertainty& expect = std::holds_alternative<PointLight>(out.lights[k]) ? lamp : sun;
    EXPECT_EQ(out.uncertainty[k].shape_covariance, expect.shape_covariance) << k;
    EXPECT_EQ(out.uncertainty[k].scale_sigma, expect.scale_sigma) << k;
  }
  EXPECT_TRUE(ParseLightsJson(LightsJson({"", in.lights, {}, {}}), "x").uncertainty.empty());
  const LightsFile partly = ParseLightsJson(
      R"({"point_lights": [{"position": [0, 0, 1], "intensity": [1, 1, 1]},
                           {"position": [0, 0, 2], "intensity": [1, 1, 1], "intensity_sigma": [0.5, 0.5, 0.5]}]})",
      "x");
  ASSERT_EQ(partly.uncertainty.size(), 2u);
  EXPECT_FALSE(partly.uncertainty[0].scale_sigma.allFinite());
  EXPECT_EQ(partly.uncertainty[1].scale_sigma, Eigen::Vector3d::Constant(0.5));
  EXPECT_FALSE(partly.uncertainty[1].shape_covariance.allFinite());
  for (const char* bad :
       {R"({"point_lights": [{"position": [0, 0, 0], "intensity": [1, 1, 1], "intensity_sigma": [1, -1, 1]}]})",
        R"({"point_lights": [{"position": [0, 0, 0], "intensity": [1, 1, 1], "intensity_sigma": [1, 1]}]})",
        R"({"point_lights": [{"position": [0, 0, 0], "intensity": [1, 1, 1], "position_covariance": [[1, 0, 0]]}]})",
        R"({"directional_lights": [{"direction": [0, 0, 1], "irradiance": [1, 1, 1],
                                   "direction_covariance": [[1, 0, 0], [0, 1, 0], [0, 0, "x"]]}]})"})
    EXPECT_THROW(ParseLightsJson(bad, "x"), InputError) << bad;
}

}  // namespace
}  // namespace lp
