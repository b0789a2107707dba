#include "estimation/lights_file.h"

#include <cmath>

#include <nlohmann/json.hpp>

#include "common/error.h"

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
  if (!j.contains("point_lights")) return out;
  if (!j["point_lights"].is_array()) throw InputError(name, "\"point_lights\" must be an array");
  const auto vec3 = [&](const json& l, const char* key) {
    if (!l.contains(key)) throw InputError(name, std::string("a point light has no \"") + key + "\"");
    const json& v = l[key];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      throw InputError(name, std::string("point light \"") + key + "\" must be 3 numbers");
    const Eigen::Vector3d x(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    if (!x.allFinite()) throw InputError(name, std::string("point light \"") + key + "\" is not finite");
    return x;
  };
  for (const json& l : j["point_lights"]) {
    if (!l.is_object()) throw InputError(name, "a point light must be an object");
    PointLight p;
    p.position = vec3(l, "position");
    p.intensity = vec3(l, "intensity");
    if (p.intensity.minCoeff() < 0) throw InputError(name, "a point light's intensity is negative");
    if (l.contains("radius")) {
      if (!l["radius"].is_number() || !std::isfinite(l["radius"].get<double>()) || l["radius"].get<double>() < 0)
        throw InputError(name, "a point light's \"radius\" must be a number >= 0");
      p.radius = l["radius"].get<double>();
    }
    out.point_lights.push_back(p);
  }
  return out;
}

}  // namespace lp
