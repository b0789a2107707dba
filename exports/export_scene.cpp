#include "exports/export_scene.h"

#include <algorithm>
#include <cmath>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_io.h"
#include "estimation/lights/emitter_light.h"
#include "estimation/lights_file.h"
#include "exports/blender.h"
#include "exports/gltf.h"
#include "exports/sh.h"
#include "scene/scene_bundle.h"

namespace lp {
namespace fs = std::filesystem;

ExportScene LoadExportScene(const fs::path& scene_dir, const fs::path& estimate_dir) {
  const fs::path lights_path = estimate_dir / "lights.json";
  const LightsFile lights = ReadLightsFile(lights_path);
  ExportScene s;
  s.lights = lights.lights;
  s.uncertainty = lights.uncertainty;
  if (!lights.environment.empty()) {
    s.environment = ReadEquirectMap(estimate_dir / lights.environment);
  }
  SceneBundle b = LoadSceneBundle(scene_dir);
  s.up = b.up.normalized();
  const fs::path refined = estimate_dir / "albedo_mesh.ply";
  if (fs::exists(refined)) {
    s.mesh = ReadPly(refined);
    SanitizeMesh(&s.mesh, refined.string());
    s.mesh_source = refined.string();
  } else {
    s.mesh = std::move(b.mesh);
    s.mesh_source = (b.dir / b.mesh_file).string();
  }
  if (s.mesh.normals.size() != s.mesh.positions.size()) ComputeVertexNormals(&s.mesh);
  const std::size_t triangles = s.mesh.triangles.size();
  s.mesh = WithoutShapes(s.mesh, lights.openings);
  s.openings = lights.openings.size();
  s.opening_triangles = triangles - s.mesh.triangles.size();
  s.mesh.shaded.clear();
  for (const View& v : b.views) s.cameras.push_back(v.camera);
  return s;
}

double SplitColour(const Eigen::Vector3d& rgb, Eigen::Vector3d* colour) {
  const double m = rgb.maxCoeff();
  *colour = m > 0 ? Eigen::Vector3d(rgb / m) : Eigen::Vector3d::Ones();
  return std::max(m, 0.0);
}

ExportFormat ParseExportFormat(const std::string& name) {
  if (name == "blender") return ExportFormat::kBlender;
  if (name == "gltf") return ExportFormat::kGltf;
  if (name == "sh") return ExportFormat::kSh;
  throw InputError("--format: expected blender, gltf or sh, got '" + name + "'");
}

const char* ToString(ExportFormat format) {
  switch (format) {
    case ExportFormat::kBlender: return "blender";
    case ExportFormat::kGltf: return "gltf";
    case ExportFormat::kSh: return "sh";
  }
  return "?";
}

std::vector<std::string> WriteExport(const ExportScene& scene, ExportFormat format, const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(dir.string(), "cannot create the output directory: " + ec.message());
  switch (format) {
    case ExportFormat::kBlender: return WriteBlenderExport(scene, dir);
    case ExportFormat::kGltf: return WriteGltfExport(scene, dir);
    case ExportFormat::kSh: return WriteShExport(scene, dir);
  }
  return {};
}

}  // namespace lp
