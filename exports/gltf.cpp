#include "exports/gltf.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/image_io.h"
#include "estimation/lights/emitter_light.h"
#include "exports/axes.h"

namespace lp {
namespace fs = std::filesystem;
using nlohmann::json;
namespace {

constexpr int kFloat = 5126, kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;

/// scene.bin and the views and accessors into it.
class Buffer {
 public:
  /// Appends floats (`components` per element) and returns the accessor's index.
  int AddVec3(const std::vector<Eigen::Vector3f>& values, bool bounds, json* gltf) {
    const std::size_t offset = Append(values.data(), values.size() * sizeof(Eigen::Vector3f));
    json accessor = {{"bufferView", AddView(offset, values.size() * 12, kArrayBuffer, gltf)},
                     {"componentType", kFloat}, {"count", values.size()}, {"type", "VEC3"}};
    if (bounds) {
      Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
      for (const auto& v : values) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
      accessor["min"] = {lo.x(), lo.y(), lo.z()};
      accessor["max"] = {hi.x(), hi.y(), hi.z()};
    }
    (*gltf)["accessors"].push_back(accessor);
    return static_cast<int>((*gltf)["accessors"].size()) - 1;
  }
  int AddIndices(const std::vector<Eigen::Vector3i>& triangles, json* gltf) {
    std::vector<std::uint32_t> idx;
    idx.reserve(3 * triangles.size());
    for (const auto& t : triangles)
      for (int k = 0; k < 3; ++k) idx.push_back(static_cast<std::uint32_t>(t[k]));
    const std::size_t offset = Append(idx.data(), idx.size() * 4);
    (*gltf)["accessors"].push_back({{"bufferView", AddView(offset, idx.size() * 4, kElementArrayBuffer, gltf)},
                                    {"componentType", kUnsignedInt}, {"count", idx.size()}, {"type", "SCALAR"}});
    return static_cast<int>((*gltf)["accessors"].size()) - 1;
  }
  const std::string& bytes() const { return bytes_; }

 private:
  std::size_t Append(const void* p, std::size_t n) {
    while (bytes_.size() % 4) bytes_.push_back('\0');
    const std::size_t offset = bytes_.size();
    bytes_.append(static_cast<const char*>(p), n);
    return offset;
  }
  static int AddView(std::size_t offset, std::size_t length, int target, json* gltf) {
    (*gltf)["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}, {"target", target}});
    return static_cast<int>((*gltf)["bufferViews"].size()) - 1;
  }
  std::string bytes_;
};

json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// Column-major, as glTF stores node matrices.
json ColumnMajor(const Eigen::Matrix4d& m) {
  json a = json::array();
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) a.push_back(m(r, c));
  return a;
}

/// Which of `emitters` each triangle of the mesh lies on (its centroid on the emitter's
/// triangles, either side), -1 for none.
std::vector<int> EmitterOfTriangle(const Mesh& mesh, const std::vector<EmitterLight>& emitters) {
  std::vector<int> of(mesh.triangles.size(), -1);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    const Eigen::Vector3d centroid =
        ((mesh.positions[tri[0]] + mesh.positions[tri[1]] + mesh.positions[tri[2]]) / 3.0f).cast<double>();
    for (std::size_t e = 0; e < emitters.size() && of[t] < 0; ++e)
      if (emitters[e].shape && !emitters[e].in_a_hole && EmitterTriangleAt(*emitters[e].shape, centroid) >= 0)
        of[t] = static_cast<int>(e);  // (a pane over a hole is on none: PaneOverAHole)
  }
  return of;
}

/// Lambertian: the vertex colour is the albedo (base colour x COLOR_0), no metal, fully
/// rough, no specular layer.
json AlbedoMaterial(const std::string& name) {
  return {{"name", name},
          {"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 1}}, {"metallicFactor", 0.0}, {"roughnessFactor", 1.0}}},
          {"extensions", {{"KHR_materials_specular", {{"specularFactor", 0.0}}}}}};
}

/// A glowing surface's material: its albedo as every other face's, and its radiance as the
/// emission, in nits (cd/m^2, at the lights' 683 lm/W): a colour whose largest channel is 1
/// times KHR_materials_emissive_strength. One-sided, as the emitter is.
json EmitterMaterial(const EmitterLight& e) {
  json m = AlbedoMaterial("emitter_" + std::to_string(e.id));
  Eigen::Vector3d colour;
  const double strength = SplitColour(e.radiance, &colour);
  m["emissiveFactor"] = Vec(colour);
  m["extensions"]["KHR_materials_emissive_strength"] = {{"emissiveStrength", kLumensPerWatt * strength}};
  m["doubleSided"] = false;
  m["extras"] = {{"radiance", Vec(e.radiance)}, {"power", Vec(e.Power())}, {"area", e.Area()}};
  return m;
}

void UseEmissiveStrength(json* gltf) {
  json& used = (*gltf)["extensionsUsed"];
  if (std::find(used.begin(), used.end(), "KHR_materials_emissive_strength") == used.end())
    used.push_back("KHR_materials_emissive_strength");
}

/// A pane over a hole in the mesh (EmitterLight::in_a_hole) as a primitive of its own: its
/// triangles wound to face the side that emits, black (it only glows).
json PaneOverAHole(const EmitterLight& e, const Eigen::Matrix3f& G, Buffer* buffer, json* gltf) {
  const EmitterShape& sh = *e.shape;
  std::vector<Eigen::Vector3f> positions, normals, colours;
  std::vector<Eigen::Vector3i> triangles;
  for (std::size_t t = 0; t < sh.a.size(); ++t) {
    const bool along = (sh.b[t] - sh.a[t]).cross(sh.c[t] - sh.a[t]).dot(sh.normal[t]) >= 0;
    const int n = static_cast<int>(positions.size());
    for (const Eigen::Vector3f& p : {sh.a[t], along ? sh.b[t] : sh.c[t], along ? sh.c[t] : sh.b[t]}) {
      positions.push_back(G * p);
      normals.push_back((G * sh.normal[t]).normalized());
      colours.push_back(Eigen::Vector3f::Zero());
    }
    triangles.push_back({n, n + 1, n + 2});
  }
  (*gltf)["materials"].push_back(EmitterMaterial(e));
  return {{"attributes",
           {{"POSITION", buffer->AddVec3(positions, true, gltf)}, {"NORMAL", buffer->AddVec3(normals, false, gltf)},
            {"COLOR_0", buffer->AddVec3(colours, false, gltf)}}},
          {"indices", buffer->AddIndices(triangles, gltf)},
          {"material", static_cast<int>((*gltf)["materials"].size()) - 1},
          {"mode", 4}};
}

/// The mesh as one primitive per material: the faces that glow (each emitter's) apart from
/// the rest, all sharing the vertices; a pane over a hole a primitive of its own.
void AddMesh(const ExportScene& s, const Eigen::Matrix3f& G, Buffer* buffer, json* gltf) {
  std::vector<Eigen::Vector3f> positions, normals;
  positions.reserve(s.mesh.positions.size());
  for (const auto& p : s.mesh.positions) positions.push_back(G * p);
  for (const auto& n : s.mesh.normals) normals.push_back((G * n).normalized());
  json attributes = {{"POSITION", buffer->AddVec3(positions, true, gltf)},
                     {"NORMAL", buffer->AddVec3(normals, false, gltf)},
                     {"COLOR_0", buffer->AddVec3(s.mesh.albedo, false, gltf)}};  // linear, as glTF's are
  const std::vector<EmitterLight> emitters = OfKind<EmitterLight>(s.lights);
  const std::vector<int> of = EmitterOfTriangle(s.mesh, emitters);
  json primitives = json::array();
  for (int e = -1; e < static_cast<int>(emitters.size()); ++e) {
    std::vector<Eigen::Vector3i> triangles;
    for (std::size_t t = 0; t < of.size(); ++t)
      if (of[t] == e) triangles.push_back(s.mesh.triangles[t]);
    if (triangles.empty() && (e >= 0 || !emitters.empty())) continue;  // a mesh keeps one primitive
    (*gltf)["materials"].push_back(e < 0 ? AlbedoMaterial("albedo") : EmitterMaterial(emitters[e]));
    primitives.push_back({{"attributes", attributes}, {"indices", buffer->AddIndices(triangles, gltf)},
                          {"material", static_cast<int>((*gltf)["materials"].size()) - 1}, {"mode", 4}});
    if (e >= 0) UseEmissiveStrength(gltf);
  }
  for (const EmitterLight& e : emitters)
    if (e.in_a_hole && e.shape && !e.shape->a.empty()) {
      primitives.push_back(PaneOverAHole(e, G, buffer, gltf));
      UseEmissiveStrength(gltf);
    }
  (*gltf)["meshes"].push_back({{"name", "lightprobe"}, {"primitives", primitives}});
  (*gltf)["nodes"].push_back({{"name", "lightprobe_mesh"}, {"mesh", 0}});
}

void AddCameras(const ExportScene& s, const Eigen::Matrix3d& G, json* gltf) {
  Eigen::Matrix4d to_gltf = Eigen::Matrix4d::Identity();
  to_gltf.block<3, 3>(0, 0) = G;
  const Eigen::Matrix4d flip = Eigen::Vector4d(1, -1, -1, 1).asDiagonal();  // OpenCV axes to glTF's camera's
  for (std::size_t k = 0; k < s.cameras.size(); ++k) {
    const Camera& c = s.cameras[k];
    const double yfov = 2 * std::atan(0.5 * c.height / c.fy);
    (*gltf)["cameras"].push_back({{"name", "keyframe_" + std::to_string(k)},
                                  {"type", "perspective"},
                                  {"perspective",
                                   {{"yfov", yfov}, {"aspectRatio", (c.width / c.fx) / (c.height / c.fy)},
                                    {"znear", 0.01}, {"zfar", 1000.0}}},
                                  {"extras", {{"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy},
                                              {"cx", c.cx}, {"cy", c.cy}}}});
    (*gltf)["nodes"].push_back({{"name", "keyframe_" + std::to_string(k)},
                                {"camera", static_cast<int>(k)},
                                {"matrix", ColumnMajor(to_gltf * c.world_from_camera * flip)}});
  }
}

void AddLights(const ExportScene& s, const Eigen::Matrix3d& G, json* gltf) {
  json lights = json::array();
  auto add_node = [&](json node) {
    node["extensions"] = {{"KHR_lights_punctual", {{"light", static_cast<int>(lights.size()) - 1}}}};
    (*gltf)["nodes"].push_back(node);
  };
  const std::vector<PointLight> points = OfKind<PointLight>(s.lights);
  for (std::size_t k = 0; k < points.size(); ++k) {
    const PointLight& l = points[k];
    Eigen::Vector3d colour;
    const double i = SplitColour(l.intensity, &colour);
    const std::string name = "point_light_" + std::to_string(k);
    lights.push_back({{"name", name}, {"type", "point"}, {"color", Vec(colour)}, {"intensity", kLumensPerWatt * i},
                      {"extras", {{"radius", l.radius}, {"radiant_intensity", Vec(l.intensity)}}}});
    add_node({{"name", name}, {"translation", Vec(G * l.position)}});
  }
  const std::vector<DirectionalLight> suns = OfKind<DirectionalLight>(s.lights);
  for (std::size_t k = 0; k < suns.size(); ++k) {
    const DirectionalLight& d = suns[k];
    Eigen::Vector3d colour;
    const double e = SplitColour(d.irradiance, &colour);
    const std::string name = "sun_" + std::to_string(k);
    lights.push_back({{"name", name}, {"type", "directional"}, {"color", Vec(colour)}, {"intensity", kLumensPerWatt * e},
                      {"extras", {{"angular_radius", d.angular_radius}, {"irradiance", Vec(d.irradiance)}}}});
    // A directional light shines along its node's -Z: turn +Z onto the direction towards it.
    const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), G * d.direction);
    add_node({{"name", name}, {"rotation", {q.x(), q.y(), q.z(), q.w()}}});
  }
  if (!lights.empty()) {
    (*gltf)["extensions"]["KHR_lights_punctual"] = {{"lights", lights}};
    (*gltf)["extensionsUsed"].push_back("KHR_lights_punctual");
  }
}

}  // namespace

std::vector<std::string> WriteGltfExport(const ExportScene& s, const fs::path& dir) {
  const ExportAxes axes(s.up);
  const Eigen::Matrix3d& G = axes.gltf_from_world;
  json gltf = {{"asset", {{"version", "2.0"}, {"generator", "lightprobe export --format gltf"}}},
               {"extensionsUsed", {"KHR_materials_specular"}},
               {"accessors", json::array()}, {"bufferViews", json::array()}, {"nodes", json::array()}};
  Buffer buffer;
  AddMesh(s, G.cast<float>(), &buffer, &gltf);
  AddCameras(s, G, &gltf);
  AddLights(s, G, &gltf);
  json scene_nodes = json::array();
  for (std::size_t k = 0; k < gltf["nodes"].size(); ++k) scene_nodes.push_back(k);
  gltf["scenes"] = {{{"name", "lightprobe"}, {"nodes", scene_nodes}}};
  gltf["scene"] = 0;
  gltf["buffers"] = {{{"uri", "scene.bin"}, {"byteLength", buffer.bytes().size()}}};
  std::vector<std::string> files = {"scene.gltf", "scene.bin"};
  if (s.environment.height > 0) {
    // The same picture as Blender's world.exr: three.js maps glTF's frame as Blender maps its own.
    WriteHdr(dir / "environment.hdr", BlenderWorldImage(s.environment, s.up, s.environment.height));
    files.push_back("environment.hdr");
    gltf["extras"] = {{"environment", "environment.hdr"},
                      {"environment_mapping",
                       "equirectangular, glTF frame: direction g lands on u = atan2(g.z, g.x) / 2pi + 0.5 "
                       "(from the left edge), v = asin(g.y) / pi + 0.5 (from the bottom row); three.js: "
                       "RGBELoader + EquirectangularReflectionMapping"},
                      {"radiometry", "radiance in the estimate's image units; lights in candela / lux at 683 lm/W"}};
  }
  WriteTextAtomically(dir / "scene.bin", buffer.bytes());
  WriteTextAtomically(dir / "scene.gltf", gltf.dump(2) + "\n");  // last: it names the others
  return files;
}

}  // namespace lp
