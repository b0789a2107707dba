#pragma once
/// Synthetic scenes with known lighting, like the paper's synthetic experiments:
/// procedural geometry lit by spherical area lights (deliberately not the
/// environment-map model), rendered by a path tracer with area-light support.
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "estimation/scene_bundle.h"

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
};

/// Names of the built-in scenes with a one-line description each.
std::vector<std::pair<std::string, std::string>> SynthSceneList();

/// Builds and renders scene `name` (throws InputError for an unknown name).
/// `data_dir` is where the real mesh for "frag115" is found (shared/data/mesh).
SceneBundle MakeSynthScene(const std::string& name, const SynthOptions& options,
                           const std::filesystem::path& data_dir);

/// Renders `views` of `mesh` lit by `lights` (reference images; every pixel).
std::vector<ImageRGB> RenderSphereLights(const Mesh& mesh, const std::vector<View>& views,
                                         const std::vector<SphereLight>& lights, const SynthOptions& options);

}  // namespace lp
