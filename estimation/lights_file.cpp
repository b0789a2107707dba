#include "estimation/lights_file.h"

#include <cmath>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/image_io.h"

namespace lp {
using nlohmann::json;

std::string LightsJson(const LightsFile& lights) {
  json j = json::object();
  if (!lights.environment.empty()) j["environment"] = lights.environment;
  j["point_lights"] = json::array();
  for (const PointLight& l : lights.point_lights)
    j["point_lights"].push_back({{"position", {l.position.x(), l.position.y(), l.position.z()}},
                                 {"intensity", {l.intensity.x(), l.intensity.y(), l.intensity.z()}},
                                 {"radius", l.radius}});
  j["directional_lights"] = json::array();
  for (const DirectionalLight& l : lights.directional_lights)
    j["directional_lights"].push_back({{"direction", {l.direction.x(), l.direction.y(), l.direction.z()}},
                                       {"irradiance", {l.irradiance.x(), l.irradiance.y(), l.irradiance.z()}},
                                       {"angular_radius", l.angular_radius}});
  return j.dump(2) + "\n";
}

LightsFile ParseLightsJson(const std::string& text, const std::string& name) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(name, std::string("malformed JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError(name, "expected a JSON object");
  LightsFile out;
  if (j.contains("environment")) {
    if (!j["environment"].is_string() || j["environment"].get<std::string>().empty())
      throw InputError(name, "\"environment\" must be a file name");
    out.environment = j["environment"].get<std::string>();
  }
  const auto vec3 = [&](const json& l, const char* what, const char* key) {
    if (!l.contains(key)) throw InputError(name, std::string("a ") + what + " has no \"" + key + "\"");
    const json& v = l[key];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      throw InputError(name, std::string(what) + " \"" + key + "\" must be 3 numbers");
    const Eigen::Vector3d x(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    if (!x.allFinite()) throw InputError(name, std::string(what) + " \"" + key + "\" is not finite");
    return x;
  };
  const auto number = [&](const json& l, const char* what, const char* key, double below) {
    const json& v = l[key];
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0 || !(v.get<double>() < below))
      throw InputError(name, std::string("a ") + what + "'s \"" + key + "\" must be a number >= 0" +
                                 (std::isfinite(below) ? " and below " + std::to_string(below) : std::string()));
    return v.get<double>();
  };
  const auto array = [&](const char* key) -> const json& {
    static const json kNone = json::array();
    if (!j.contains(key)) return kNone;
    if (!j[key].is_array()) throw InputError(name, std::string("\"") + key + "\" must be an array");
    return j[key];
  };
  for (const json& l : array("point_lights")) {
    if (!l.is_object()) throw InputError(name, "a point light must be an object");
    PointLight p;
    p.position = vec3(l, "point light", "position");
    p.intensity = vec3(l, "point light", "intensity");
    if (p.intensity.minCoeff() < 0) throw InputError(name, "a point light's intensity is negative");
    if (l.contains("radius")) p.radius = number(l, "point light", "radius", HUGE_VAL);
    out.point_lights.push_back(p);
  }
  for (const json& l : array("directional_lights")) {
    if (!l.is_object()) throw InputError(name, "a directional light must be an object");
    DirectionalLight d;
    d.direction = vec3(l, "directional light", "direction");
    if (!(d.direction.norm() > 0) || !std::isfinite(d.direction.norm()))
      throw InputError(name, "a directional light's \"direction\" must not be zero");
    d.direction.normalize();
    d.irradiance = vec3(l, "directional light", "irradiance");
    if (d.irradiance.minCoeff() < 0) throw InputError(name, "a directional light's irradiance is negative");
    if (l.contains("angular_radius")) d.angular_radius = number(l, "directional light", "angular_radius", M_PI / 2);
    out.directional_lights.push_back(d);
  }
  return out;
}

ImageRGB ReadEquirectMap(const std::filesystem::path& file) {
  ImageRGB map = file.extension() == ".hdr" ? ReadHdr(file) : ReadImageLinear(file);
  if (map.width != 2 * map.height) throw InputError(file.string(), "environment map must be equirectangular (width = 2*height)");
  for (float v : map.data)
    if (!std::isfinite(v) || v < 0) throw InputError(file.string(), "environment map has negative or non-finite values");
  return map;
}

}  // namespace lp
