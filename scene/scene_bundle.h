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
#include "scene/camera.h"
#include "scene/mesh.h"

namespace lp {

/// One reference image with its camera. `valid` marks pixels that are inside the
/// mask and finite and non-negative in every channel.
struct View {
  Camera camera;
  ImageRGB image;               ///< linear RGB
  std::vector<std::uint8_t> valid;  ///< width*height, 1 = use
  /// Per pixel (width*height), or empty (none known): 1 where the camera clipped it (a
  /// channel at `saturation`, or a keyframe's block holding such a pixel): its value is then a
  /// lower bound (a block's mean over its clipped pixels), and it is not `valid`.
  std::vector<std::uint8_t> clipped;
  /// Per pixel, or empty (none known): 1 where the camera clipped a pixel off the mesh (no
  /// depth, or depth in front of the surface the mesh puts there: a bulb, which often returns
  /// no depth, or a lamp before a wall). Never `valid`; the estimator proposes lamps where
  /// such blobs are (estimation/seen_lamps.h).
  std::vector<std::uint8_t> clipped_off;
  std::string image_file, mask_file, clipped_file, clipped_off_file;  ///< as named in scene.json (relative)
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
/// Saturated pixels inside the mask are marked `clipped`.
void MarkUnusablePixels(View* view);

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
