#pragma once
/// `lightprobe export`: an estimate as other programs take it (docs/formats.md, "Exports").
/// Every format carries every kind of light of lights.json: the map and each kind of
/// `Light` (a new kind gets its entry in each format here, in exports/).
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "estimation/light_uncertainty.h"
#include "estimation/lighting.h"
#include "scene/camera.h"
#include "scene/mesh.h"

namespace lp {

/// What an export is made from: the bundle's geometry and keyframe cameras, the estimate's
/// lights, all in the bundle's world frame.
struct ExportScene {
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Mesh mesh;                    ///< with vertex normals; the refined albedo when the estimate made one
  std::string mesh_source;      ///< the file it came from (for the log)
  /// Windows' openings of lights.json (openings.ply): their triangles are left out of `mesh`
  /// (no surface: the map is seen and lights the room through them); how many and how many
  /// triangles that took out.
  std::size_t openings = 0, opening_triangles = 0;
  std::vector<Camera> cameras;  ///< the keyframes', in order
  ImageRGB environment;         ///< the map, EnvMap's equirectangular convention; empty when none
  std::vector<Light> lights;    ///< every kind (each exporter writes each kind its own way)
  /// lights.json's uncertainty of each light (same order), or empty when it has none.
  std::vector<LightUncertainty> uncertainty;
};

/// Reads SCENE_DIR's bundle and ESTIMATE_DIR/lights.json with the map it names, and
/// ESTIMATE_DIR/albedo_mesh.ply in place of the bundle's mesh when it exists, with the
/// estimate's openings (windows seen through) left out of the mesh. Throws
/// InputError naming the file on any problem.
ExportScene LoadExportScene(const std::filesystem::path& scene_dir, const std::filesystem::path& estimate_dir);

/// A light's RGB as the exports carry it: a colour whose largest channel is 1 (white for a
/// dark light) times the returned strength (that channel, >= 0).
double SplitColour(const Eigen::Vector3d& rgb, Eigen::Vector3d* colour);

enum class ExportFormat { kBlender, kGltf, kSh };
/// "blender", "gltf" or "sh"; InputError otherwise.
ExportFormat ParseExportFormat(const std::string& name);
const char* ToString(ExportFormat format);

/// Writes one format into `dir` (created; each file atomically) and returns the files'
/// names, the main one first.
std::vector<std::string> WriteExport(const ExportScene& scene, ExportFormat format, const std::filesystem::path& dir);

}  // namespace lp
