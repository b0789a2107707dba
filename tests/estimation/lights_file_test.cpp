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
  const LightsFile in{"envmap.exr", {PointLight{{1, 2, 3}, {0.5, 0.25, 0}, 0.05}}};
  const LightsFile out = ParseLightsJson(LightsJson(in), "lights.json");
  EXPECT_EQ(out.environment, "envmap.exr");
  const std::vector<PointLight> lamps = OfKind<PointLight>(out.lights);
  ASSERT_EQ(out.lights.size(), 1u);
  ASSERT_EQ(lamps.size(), 1u);
  EXPECT_EQ(lamps[0].position, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(lamps[0].intensity, Eigen::Vector3d(0.5, 0.25, 0));
  EXPECT_EQ(lamps[0].radius, 0.05);
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
  const LightsFile both{"", {DirectionalLight{{0, 0, 1}, {1, 1, 1}, 0}, PointLight{{0, 0, 2}, {3, 3, 3}, 0}}};
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

}  // namespace
}  // namespace lp
