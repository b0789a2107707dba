#include "estimation/lights_file.h"

#include <cmath>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/image_io.h"

namespace lp {
using nlohmann::json;

const char* LightsKey(const PointLight&) { return "point_lights"; }
const char* LightsKey(const DirectionalLight&) { return "directional_lights"; }

namespace {

json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

json ToJson(const PointLight& l) {
  return {{"position", Vec(l.position)}, {"intensity", Vec(l.intensity)}, {"radius", l.radius}};
}
json ToJson(const DirectionalLight& l) {
  return {{"direction", Vec(l.direction)}, {"irradiance", Vec(l.irradiance)}, {"angular_radius", l.angular_radius}};
}

/// Reads one light's fields, each error a one-line InputError naming the file.
struct FieldReader {
  const std::string& name;
  Eigen::Vector3d Vec3(const json& l, const char* what, const char* key) const {
    if (!l.contains(key)) throw InputError(name, std::string("a ") + what + " has no \"" + key + "\"");
    const json& v = l[key];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      throw InputError(name, std::string(what) + " \"" + key + "\" must be 3 numbers");
    const Eigen::Vector3d x(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    if (!x.allFinite()) throw InputError(name, std::string(what) + " \"" + key + "\" is not finite");
    return x;
  }
  double Number(const json& l, const char* what, const char* key, double below) const {
    const json& v = l[key];
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0 || !(v.get<double>() < below))
      throw InputError(name, std::string("a ") + what + "'s \"" + key + "\" must be a number >= 0" +
                                 (std::isfinite(below) ? " and below " + std::to_string(below) : std::string()));
    return v.get<double>();
  }
};

void Read(const json& l, const FieldReader& r, PointLight* p) {
  if (!l.is_object()) throw InputError(r.name, "a point light must be an object");
  p->position = r.Vec3(l, "point light", "position");
  p->intensity = r.Vec3(l, "point light", "intensity");
  if (p->intensity.minCoeff() < 0) throw InputError(r.name, "a point light's intensity is negative");
  if (l.contains("radius")) p->radius = r.Number(l, "point light", "radius", HUGE_VAL);
}

void Read(const json& l, const FieldReader& r, DirectionalLight* d) {
  if (!l.is_object()) throw InputError(r.name, "a directional light must be an object");
  d->direction = r.Vec3(l, "directional light", "direction");
  if (!(d->direction.norm() > 0) || !std::isfinite(d->direction.norm()))
    throw InputError(r.name, "a directional light's \"direction\" must not be zero");
  d->direction.normalize();
  d->irradiance = r.Vec3(l, "directional light", "irradiance");
  if (d->irradiance.minCoeff() < 0) throw InputError(r.name, "a directional light's irradiance is negative");
  if (l.contains("angular_radius")) d->angular_radius = r.Number(l, "directional light", "angular_radius", M_PI / 2);
}

}  // namespace

std::string LightsJson(const LightsFile& lights) {
  json j = json::object();
  if (!lights.environment.empty()) j["environment"] = lights.environment;
  ForEachKind([&](const auto& kind) { j[LightsKey(kind)] = json::array(); });
  for (const Light& light : lights.lights)
    std::visit([&](const auto& l) { j[LightsKey(l)].push_back(ToJson(l)); }, light);
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
  const FieldReader reader{name};
  ForEachKind([&](auto kind) {
    const char* key = LightsKey(kind);
    if (!j.contains(key)) return;  // (a file written before the kind existed has none)
    if (!j[key].is_array()) throw InputError(name, std::string("\"") + key + "\" must be an array");
    for (const json& l : j[key]) {
      decltype(kind) light;
      Read(l, reader, &light);
      out.lights.push_back(light);
    }
  });
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
