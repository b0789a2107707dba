#pragma once
/// The scene bundle (docs/formats.md): the on-disk contract between
/// reconstruction and estimation. Readers accept exactly the documented format;
/// the writer writes exactly it.
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "estimation/mesh.h"

namespace lp {

/// Pinhole camera, OpenCV convention (x right, y down, z forward); pixel centres at
/// integer coordinates: u = fx*X/Z + cx, v = fy*Y/Z + cy.
struct Camera {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Eigen::Matrix4d world_from_camera = Eigen::Matrix4d::Identity();

  Eigen::Vector3d center() const { return world_from_camera.block<3, 1>(0, 3); }
  /// Unit world direction of the ray through image point (u, v) (pixel units).
  Eigen::Vector3d RayDirection(double u, double v) const;
  /// Camera at `eye` looking at `target` with image up along world `up` (another axis
  /// is used if the view is parallel to it); centred principal point, square pixels.
  static Camera LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up, int w,
                       int h, double hfov_deg);
  /// Projects a world point; returns false if behind the camera.
  bool Project(const Eigen::Vector3d& world, double* u, double* v) const;
};

/// One reference image with its camera. `valid` marks pixels that are inside the
/// mask and finite and non-negative in every channel.
struct View {
  Camera camera;
  ImageRGB image;               ///< linear RGB
  std::vector<std::uint8_t> valid;  ///< width*height, 1 = use
  std::string image_file, mask_file;  ///< as named in scene.json (relative)
  /// Pixels with any channel at or above this are clipped by the camera and not used
  /// (scene.json "saturation"; an 8-bit or 16-bit PNG defaults to its top code, 1.0).
  double saturation = std::numeric_limits<double>::infinity();
  int masked_out = 0;   ///< pixels excluded by the mask
  int non_finite = 0;   ///< pixels excluded for NaN/Inf
  int negative = 0;     ///< pixels excluded for negative values
  int saturated = 0;    ///< pixels excluded for reaching `saturation`
};

/// Clears `valid` for the pixels of `view` that are non-finite, negative or saturated (in
/// any channel) and adds them to the counts; pixels already invalid are not counted again.
void MarkUnusablePixels(View* view);

/// A view's white level: the 99th-percentile luminance of its valid pixels (1 if none).
/// Renders are shown with it mapped to white, and photometric errors as a fraction of it.
float WhiteLevel(const View& view);

/// Errors are shown in viridis from 0 to this fraction of the white level, in the same
/// way everywhere: error_view*.png, the viewer's error shading and its keyframe panel.
constexpr float kErrorDisplayFraction = 0.25f;

/// The error shown for one pixel: the RMS over the three channels of rendered - observed.
inline float PixelError(const float* rendered, const float* observed) {
  float s = 0;
  for (int c = 0; c < 3; ++c) s += (rendered[c] - observed[c]) * (rendered[c] - observed[c]);
  return std::sqrt(s / 3);
}

/// PixelError of `render` against the view per pixel; -1 where the view's pixel is not
/// valid (Heatmap() shows those black).
std::vector<float> ErrorImage(const ImageRGB& render, const View& view);

struct SceneBundle {
  std::filesystem::path dir;
  std::string mesh_file = "mesh.ply";
  Mesh mesh;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  std::vector<View> views;
  int degenerate_triangles_removed = 0;
  std::optional<std::string> truth_json;  ///< raw text of truth.json when present
  /// Other text files written with the bundle, as part of it (file name, text): the
  /// reconstruction's log, trajectory and calibration. Not read back by LoadSceneBundle.
  std::vector<std::pair<std::string, std::string>> extra_files;
};

/// Reads `dir/scene.json` and everything it names. Throws InputError naming the
/// offending file and problem (missing files, malformed JSON, size mismatches,
/// a view with no usable pixel, an empty or degenerate mesh).
SceneBundle LoadSceneBundle(const std::filesystem::path& dir);

/// Parses scene.json text into a bundle skeleton (no files read); `name` is used
/// in errors. Exposed for tests and fuzzing.
SceneBundle ParseSceneJson(const std::string& text, const std::string& name);

/// Writes a bundle (scene.json, mesh.ply, view<k>.exr, mask<k>.png, truth.json
/// when set, the extra files) into `dir`, atomically as a whole: it is built in a
/// sibling temporary directory and renamed into place, replacing an existing bundle
/// (which is put back if the new one cannot move into place).
void WriteSceneBundle(const std::filesystem::path& dir, const SceneBundle& bundle);

}  // namespace lp
