#pragma once
/// Synthetic scenes with known lighting, like the paper's synthetic experiments:
/// procedural geometry lit by spherical area lights (deliberately not the
/// environment-map model), rendered by a path tracer with area-light support.
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "estimation/envmap.h"
#include "scene/scene_bundle.h"

namespace lp {

/// A spherical area light (Lambertian emitter): centre, radius (m) and RGB power (W-like units).
struct SphereLight {
  Eigen::Vector3d position;
  double radius = 0.1;
  Eigen::Vector3d rgb_power;
  /// Radiance of its surface: power / (4 pi^2 r^2).
  Eigen::Vector3d Radiance() const;
};

struct SynthOptions {
  int width = 160, height = 120;
  int spp = 256;  ///< samples per pixel of the reference image
  int bounces = 4;
  std::uint64_t seed = 7;
  /// Extra views from another viewpoint (0 or 1), appended after the fitted view: for
  /// measuring relighting on a view the fit did not use.
  int held_out_views = 0;
  /// RenderSynthFrames only: depth as a structured-light sensor (Xtion / Kinect v1) gives
  /// it (Nguyen et al. 2012): Gaussian axial noise sigma(z) = 1.2 mm + 1.9 mm (z - 0.4 m)^2,
  /// holes where the surface is seen at grazing angles (|cos| < 0.2), on half the pixels at
  /// depth discontinuities and on 0.5 % of pixels at random.
  bool depth_noise = false;
  /// RenderSynthFrames only: the sphere lights seen by the colour camera at their radiance,
  /// with no depth where they are (a bare bulb returns none to a structured-light sensor).
  bool lamps_seen = false;
};

/// The true lighting of a synthetic scene, for evaluation (never read by the estimator).
struct SynthLighting {
  std::vector<SphereLight> lights;
  /// Radiance arriving from the open sky along a world direction (none when empty); rendered
  /// by BSDF sampling, it must be smooth.
  std::function<Eigen::Vector3d(const Eigen::Vector3d&)> sky;
  /// A measured HDR environment map in the EnvMap equirect convention around the scene's up
  /// (empty when the scene is not lit by one).
  ImageRGB equirect;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< where directions are measured from
  /// False when the lights are so close that no environment map reproduces them (near-light).
  bool far = true;
};

struct SynthScene {
  SceneBundle bundle;
  SynthLighting lighting;
};

/// Names of the built-in scenes with a one-line description each.
std::vector<std::pair<std::string, std::string>> SynthSceneList();

/// Builds and renders scene `name` (throws InputError for an unknown name).
/// `data_dir` is the bundled assets/ directory: the real mesh for "frag115" is read from data_dir/mesh,
/// the HDR maps of the env-* scenes from data_dir/hdri.
SynthScene MakeSynth(const std::string& name, const SynthOptions& options, const std::filesystem::path& data_dir);
SceneBundle MakeSynthScene(const std::string& name, const SynthOptions& options,
                           const std::filesystem::path& data_dir);

/// One RGB-D frame of a synthetic scene with its true camera.
struct SynthFrame {
  Camera camera;              ///< true pose and intrinsics
  ImageRGB color;             ///< linear radiance
  std::vector<float> depth;   ///< metres along the optical axis per pixel, 0 = nothing hit
};

/// RGB-D frames of scene `name` along an arc around its centre (the first view's camera
/// turned about the up axis from -20 to +20 degrees): the capture stage's synthetic source
/// (written as a frame directory by `lightprobe synth --frames`). Every scene, the HDR-map
/// ones included (rendered from the map integrated over a fine grid, as MakeSynth does).
/// `truth_json`, when given, receives the scene's truth.json text (as in its bundle).
std::vector<SynthFrame> RenderSynthFrames(const std::string& name, const SynthOptions& options,
                                          const std::filesystem::path& data_dir, int frames,
                                          std::string* truth_json = nullptr);

/// The true lighting integrated over each cell of `env`: mean radiance per cell (3 per
/// cell), as seen from the scene centre. Empty when the lighting is not far (near-light).
std::vector<double> TrueCellRadiance(const SynthLighting& lighting, const EnvMap& env);

/// Renders `views` of `mesh` lit by `lights` and the sky (reference images; every pixel).
/// An equirect map in `lighting` is not used here (see MakeSynth).
std::vector<ImageRGB> RenderSphereLights(const Mesh& mesh, const std::vector<View>& views,
                                         const SynthLighting& lighting, const SynthOptions& options);

}  // namespace lp
