#include "estimation/lights_file.h"

#include <cmath>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/image_io.h"
#include "common/atomic_file.h"
#include "scene/mesh.h"

namespace lp {
using nlohmann::json;

const char* LightsKey(const PointLight&) { return "point_lights"; }
const char* LightsKey(const DirectionalLight&) { return "directional_lights"; }
const char* LightsKey(const EmitterLight&) { return "emitters"; }

namespace {

json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

json ToJson(const PointLight& l) {
  json j = {{"position", Vec(l.position)}, {"intensity", Vec(l.intensity)}, {"radius", l.radius}};
  if (l.held) j["held"] = true;  // (its place where the cameras saw it, not fitted)
  return j;
}
json ToJson(const DirectionalLight& l) {
  return {{"direction", Vec(l.direction)}, {"irradiance", Vec(l.irradiance)}, {"angular_radius", l.angular_radius}};
}
json ToJson(const EmitterLight& l) {
  json j = {{"id", l.id}, {"radiance", Vec(l.radiance)}, {"power", Vec(l.Power())}, {"area", l.Area()},
            {"two_sided", false}};
  if (l.in_a_hole) j["in_a_hole"] = true;  // (a window's pane over a hole in the mesh)
  return j;
}

/// A number, or null where it is not finite (JSON has no infinity).
json Number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }
json Matrix(const Eigen::Matrix3d& m) {
  json rows = json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({Number(m(r, 0)), Number(m(r, 1)), Number(m(r, 2))});
  return rows;
}
json Sigma(const Eigen::Vector3d& v) { return {Number(v.x()), Number(v.y()), Number(v.z())}; }

/// Each kind's keys for its uncertainty.
struct UncertaintyKeys {
  const char* shape;
  const char* scale;
};
UncertaintyKeys KeysOf(const PointLight&) { return {"position_covariance", "intensity_sigma"}; }
UncertaintyKeys KeysOf(const DirectionalLight&) { return {"direction_covariance", "irradiance_sigma"}; }
UncertaintyKeys KeysOf(const EmitterLight&) { return {nullptr, "radiance_sigma"}; }  // (no shape to be unsure of)

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
  /// A number or null (infinite), the matrix's or sigma's entry `key` names.
  double Entry(const json& v, const char* key) const {
    if (v.is_null()) return INFINITY;
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      throw InputError(name, std::string("\"") + key + "\" must hold numbers (or null: unknown)");
    return v.get<double>();
  }
  /// A light's uncertainty, when it has one (else everything unknown).
  LightUncertainty Uncertainty(const json& l, const UncertaintyKeys& keys) const {
    LightUncertainty u;
    u.shape_covariance.setConstant(INFINITY);
    u.scale_sigma.setConstant(INFINITY);
    if (keys.shape && l.contains(keys.shape)) {
      const json& m = l[keys.shape];
      if (!m.is_array() || m.size() != 3)
        throw InputError(name, std::string("\"") + keys.shape + "\" must be 3 rows of 3 numbers");
      for (int r = 0; r < 3; ++r) {
        if (!m[r].is_array() || m[r].size() != 3)
          throw InputError(name, std::string("\"") + keys.shape + "\" must be 3 rows of 3 numbers");
        for (int c = 0; c < 3; ++c) u.shape_covariance(r, c) = Entry(m[r][c], keys.shape);
      }
    }
    if (l.contains(keys.scale)) {
      const json& v = l[keys.scale];
      if (!v.is_array() || v.size() != 3) throw InputError(name, std::string("\"") + keys.scale + "\" must be 3 numbers");
      for (int c = 0; c < 3; ++c) {
        u.scale_sigma[c] = Entry(v[c], keys.scale);
        if (u.scale_sigma[c] < 0) throw InputError(name, std::string("\"") + keys.scale + "\" is negative");
      }
    }
    return u;
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
  if (l.contains("held")) {
    if (!l["held"].is_boolean()) throw InputError(r.name, "a point light's \"held\" must be true or false");
    p->held = l["held"].get<bool>();
  }
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

void Read(const json& l, const FieldReader& r, EmitterLight* e) {
  if (!l.is_object()) throw InputError(r.name, "an emitter must be an object");
  if (!l.contains("id") || !l["id"].is_number_integer() || l["id"].get<long long>() < 0 ||
      l["id"].get<long long>() > 1000000)
    throw InputError(r.name, "an emitter's \"id\" must be a whole number from 0");
  e->id = l["id"].get<int>();
  e->radiance = r.Vec3(l, "emitter", "radiance");
  if (e->radiance.minCoeff() < 0) throw InputError(r.name, "an emitter's radiance is negative");
  if (l.contains("in_a_hole")) {
    if (!l["in_a_hole"].is_boolean()) throw InputError(r.name, "an emitter's \"in_a_hole\" must be true or false");
    e->in_a_hole = l["in_a_hole"].get<bool>();
  }
}

}  // namespace

std::string LightsJson(const LightsFile& lights) {
  json j = json::object();
  if (!lights.environment.empty()) j["environment"] = lights.environment;
  LP_CHECK(lights.uncertainty.empty() || lights.uncertainty.size() == lights.lights.size(),
           "an uncertainty per light, or none");
  ForEachKind([&](const auto& kind) { j[LightsKey(kind)] = json::array(); });
  for (std::size_t k = 0; k < lights.lights.size(); ++k)
    std::visit(
        [&](const auto& l) {
          json entry = ToJson(l);
          if (!lights.uncertainty.empty()) {
            const UncertaintyKeys keys = KeysOf(l);
            if (keys.shape) entry[keys.shape] = Matrix(lights.uncertainty[k].shape_covariance);
            entry[keys.scale] = Sigma(lights.uncertainty[k].scale_sigma);
          }
          j[LightsKey(l)].push_back(entry);
        },
        lights.lights[k]);
  if (!lights.openings.empty()) {
    j["openings"] = json::array();
    for (std::size_t k = 0; k < lights.openings.size(); ++k)
      j["openings"].push_back({{"id", k}, {"area", lights.openings[k] ? lights.openings[k]->area : 0.0}});
  }
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
      const UncertaintyKeys keys = KeysOf(light);
      if ((keys.shape && l.contains(keys.shape)) || l.contains(keys.scale)) {
        out.uncertainty.resize(out.lights.size() - 1, reader.Uncertainty(json::object(), keys));
        out.uncertainty.push_back(reader.Uncertainty(l, keys));
      }
    }
  });
  if (!out.uncertainty.empty()) {  // the lights after the last that had one: unknown
    LightUncertainty unknown;
    unknown.shape_covariance.setConstant(INFINITY);
    unknown.scale_sigma.setConstant(INFINITY);
    out.uncertainty.resize(out.lights.size(), unknown);
  }
  if (j.contains("openings")) {
    if (!j["openings"].is_array()) throw InputError(name, "\"openings\" must be an array");
    for (const json& o : j["openings"])
      if (!o.is_object() || !o.contains("id") || !o["id"].is_number_integer() ||
          o["id"].get<long long>() != static_cast<long long>(out.openings.size()))
        throw InputError(name, "\"openings\" must hold {\"id\": 0, ...}, {\"id\": 1, ...} in order");
      else
        out.openings.push_back(nullptr);  // (the shapes: openings.ply, ReadLightsFile)
  }
  return out;
}

namespace {

/// Each id's triangles of `ply` (emitters.ply's layout), as shapes facing their vertices' normals.
std::map<int, std::shared_ptr<const EmitterShape>> ShapesOf(const std::filesystem::path& ply, const char* what) {
  if (!std::filesystem::exists(ply)) throw InputError(ply.string(), std::string("missing: lights.json names ") + what);
  const Mesh mesh = ReadPly(ply);
  if (mesh.label.size() != mesh.positions.size()) throw InputError(ply.string(), "its vertices have no \"emitter\" id");
  std::map<int, std::vector<int>> triangles;  // per id
  std::map<int, std::vector<Eigen::Vector3f>> facing;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const int v = mesh.triangles[t][0];
    triangles[mesh.label[v]].push_back(static_cast<int>(t));
    facing[mesh.label[v]].push_back(mesh.normals.empty() ? Eigen::Vector3f::Zero() : mesh.normals[v]);
  }
  std::map<int, std::shared_ptr<const EmitterShape>> out;
  for (const auto& [id, ts] : triangles) out[id] = MakeEmitterShape(mesh, ts, facing[id]);
  return out;
}

}  // namespace

LightsFile ReadLightsFile(const std::filesystem::path& path) {
  LightsFile file = ParseLightsJson(ReadTextFile(path), path.string());
  if (!file.openings.empty()) {
    const std::filesystem::path ply = path.parent_path() / "openings.ply";
    const auto shapes = ShapesOf(ply, "openings");
    for (std::size_t k = 0; k < file.openings.size(); ++k) {
      const auto it = shapes.find(static_cast<int>(k));
      if (it == shapes.end()) throw InputError(ply.string(), "has no triangles of opening " + std::to_string(k));
      file.openings[k] = it->second;
    }
  }
  bool any = false;
  for (const Light& l : file.lights) any |= std::holds_alternative<EmitterLight>(l);
  if (!any) return file;
  const std::filesystem::path ply = path.parent_path() / "emitters.ply";
  const auto shapes = ShapesOf(ply, "emitters");
  for (Light& l : file.lights)
    if (EmitterLight* e = std::get_if<EmitterLight>(&l)) {
      const auto it = shapes.find(e->id);
      if (it == shapes.end()) throw InputError(ply.string(), "has no triangles of emitter " + std::to_string(e->id));
      e->shape = it->second;
    }
  return file;
}

void WriteEmittersPly(const std::filesystem::path& file, const std::vector<Light>& lights) {
  Mesh out;
  for (const Light& l : lights) {
    const EmitterLight* e = std::get_if<EmitterLight>(&l);
    if (!e || !e->shape) continue;
    const EmitterShape& s = *e->shape;
    const double top = std::max(e->radiance.maxCoeff(), 1e-30);
    const Eigen::Vector3f look = (e->radiance / top).cast<float>();
    for (std::size_t t = 0; t < s.a.size(); ++t) {
      const int base = static_cast<int>(out.positions.size());
      for (const Eigen::Vector3f& p : {s.a[t], s.b[t], s.c[t]}) {
        out.positions.push_back(p);
        out.normals.push_back(s.normal[t]);
        out.albedo.push_back(look);
        out.label.push_back(e->id);
        out.emission.push_back(e->radiance.cast<float>());
      }
      // (wound so that its normal is the side that emits)
      const bool along = (s.b[t] - s.a[t]).cross(s.c[t] - s.a[t]).dot(s.normal[t]) >= 0;
      out.triangles.emplace_back(base, along ? base + 1 : base + 2, along ? base + 2 : base + 1);
    }
  }
  if (!out.triangles.empty()) WritePly(file, out);
}

void WriteOpeningsPly(const std::filesystem::path& file,
                      const std::vector<std::shared_ptr<const EmitterShape>>& openings) {
  Mesh out;
  for (std::size_t k = 0; k < openings.size(); ++k) {
    if (!openings[k]) continue;
    const EmitterShape& s = *openings[k];
    for (std::size_t t = 0; t < s.a.size(); ++t) {
      const int base = static_cast<int>(out.positions.size());
      for (const Eigen::Vector3f& p : {s.a[t], s.b[t], s.c[t]}) {
        out.positions.push_back(p);
        out.normals.push_back(s.normal[t]);
        out.albedo.push_back(Eigen::Vector3f::Ones());
        out.label.push_back(static_cast<int>(k));
      }
      out.triangles.emplace_back(base, base + 1, base + 2);
    }
  }
  if (!out.triangles.empty()) WritePly(file, out);
}

ImageRGB ReadEquirectMap(const std::filesystem::path& file) {
  ImageRGB map = file.extension() == ".hdr" ? ReadHdr(file) : ReadImageLinear(file);
  if (map.width != 2 * map.height) throw InputError(file.string(), "environment map must be equirectangular (width = 2*height)");
  for (float v : map.data)
    if (!std::isfinite(v) || v < 0) throw InputError(file.string(), "environment map has negative or non-finite values");
  return map;
}

}  // namespace lp
