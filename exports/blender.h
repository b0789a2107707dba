#pragma once
/// The Blender export: DIR/scene.py (builds the scene in Blender, and saves or renders it),
/// DIR/world.exr (the map in Blender's equirectangular mapping) and DIR/mesh.ply.
/// docs/formats.md, "Exports".
#include <filesystem>
#include <string>
#include <vector>

#include "exports/export_scene.h"

namespace lp {

/// Writes the three files (world.exr only when there is a map); returns their names.
std::vector<std::string> WriteBlenderExport(const ExportScene& scene, const std::filesystem::path& dir);

/// What scene.py runs after its data (exports/blender_script.cpp): fixed Python that reads
/// the data block WriteBlenderExport puts before it.
extern const char* const kBlenderSceneScript;

/// A Blender camera from a keyframe's pinhole camera (OpenCV axes, pixel centres at integers):
/// focal length in mm on a 36 mm wide sensor fitted horizontally, the principal point as
/// Blender's lens shift, the pixel aspect for fx != fy, and the object's world matrix in
/// Blender's frame (its camera looks down its -Z with +Y up).
struct BlenderCamera {
  int width = 0, height = 0;
  double lens_mm = 0, sensor_width_mm = 36, shift_x = 0, shift_y = 0;
  double pixel_aspect_x = 1, pixel_aspect_y = 1;
  Eigen::Matrix4d matrix_world = Eigen::Matrix4d::Identity();
};
BlenderCamera ToBlenderCamera(const Camera& camera, const Eigen::Matrix3d& blender_from_world);

}  // namespace lp
