// Independent truth for the light's place: a scene bundle rendered by Blender Cycles
// (tests/data/cycles, 4096 spp, a point light 1.8 m from the room's centre, known
// albedo). Neither the images nor the light's position went through this project's
// renderer, so a convention error shared by the renderer and the estimator (a mirrored
// azimuth, a flipped up, a transposed pose) cannot pass here as it can on self-made scenes.
// The environment map is a far-light model: until point lights exist, the estimate can
// only be asked to put the lamp on its side of the scene, not at its place.
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/image_io.h"
#include "estimation/estimator.h"
#include "estimation/path_tracer.h"
#include "estimation/truth.h"
#include "scene/scene_bundle.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

Eigen::Vector3d Vec(const nlohmann::json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }

TEST(Cycles, TheLampComesBackOnItsSideOfTheScene) {
  const fs::path dir = fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data" / "cycles" / "cornerbox_one_light";
  const SceneBundle bundle = LoadSceneBundle(dir);
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(dir / "truth.json"));
  const Eigen::Vector3d lamp = Vec(truth["lights"][0]["position"]);
  const Eigen::Vector3d centre = Vec(truth["scene_bbox"]["centre"]);
  const Eigen::Vector3d to_lamp = (lamp - centre).normalized();  // (0.55, 0.25, 0.80)

  EstimateOptions o;
  o.tracer.spp = 64;
  o.max_rounds = 3;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  ASSERT_FALSE(r.dominant.empty());
  const Eigen::Vector3d d = r.dominant[0];
  const double angle = AngleDeg(d, to_lamp);
  std::printf("dominant direction (%.3f, %.3f, %.3f), %.1f deg from the lamp; relative RMSE %.3f\n", d.x(), d.y(),
              d.z(), angle, r.final_relative_rmse);
  // On the lamp's side of the scene: within 90 degrees of it and above the horizon (the lamp
  // is 1.45 m above the centre). Measured: (-0.70, 0.01, 0.71), 79 degrees from the lamp
  // (77 at the estimate's defaults): the far-light model cannot place a lamp this close,
  // which is why this bound is loose; a flipped up or a map turned upside down fails it.
  EXPECT_LT(angle, 90);
  EXPECT_GT(d.dot(bundle.up), 0.3);
  // It explains the image only roughly (0.365 measured, 0.34 at the defaults).
  EXPECT_LT(r.final_relative_rmse, 0.5);
}

/// Mean of one channel of an image over a block of pixels [x0, x1) x [y0, y1).
double BlockMean(const ImageRGB& im, int c, int x0, int x1, int y0, int y1) {
  double s = 0;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) s += im.at(x, y)[c];
  return s / ((x1 - x0) * (y1 - y0));
}

// Multi-bounce radiometry against an independent renderer: an open box of albedo 0.79 with
// a coloured block inside, under a uniform white sky of radiance 1, rendered by Cycles
// (tests/data/cycles/interreflection, made by scripts/make-cycles-interreflection.py):
// light bounces many times between the walls, so Russian roulette, the bounce loop and
// every radiometric factor (1/pi of the BSDF, the cosine, the sky's radiance) show in the
// pixel values, and the camera's half-pixel convention in the edges.
TEST(Cycles, ForwardRenderOfAnInterreflectingBoxMatches) {
  const fs::path dir = fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data" / "cycles" / "interreflection";
  const SceneBundle bundle = LoadSceneBundle(dir);
  const ImageRGB& cycles = bundle.views[0].image;
  const RayTracer scene(bundle.mesh);
  const EnvMap env(9, bundle.up);
  const std::vector<double> white(3 * env.size(), 1.0);
  TracerOptions t;
  t.spp = 512;
  t.bounces = 64;
  t.seed = 5;
  const ImageRGB ours =
      RenderEnvironment(scene, env, bundle.views, white, CellSampler(env, white, {}, 0.05), t, true).at(0);
  double se = 0, sum = 0;
  for (std::size_t i = 0; i < ours.data.size(); ++i) {
    se += (ours.data[i] - cycles.data[i]) * (ours.data[i] - cycles.data[i]);
    sum += cycles.data[i];
  }
  const double mean = sum / ours.data.size(), rel_rmse = std::sqrt(se / ours.data.size()) / mean;
  std::printf("relative RMSE %.4f over %zu pixels\n", rel_rmse, ours.pixels());
  // Block means (8x8 pixels) per channel: the noise of both averages down, the radiometry does not.
  double worst = 0;
  for (int by = 0; by + 8 <= ours.height; by += 8)
    for (int bx = 0; bx + 8 <= ours.width; bx += 8)
      for (int c = 0; c < 3; ++c) {
        const double a = BlockMean(ours, c, bx, bx + 8, by, by + 8), b = BlockMean(cycles, c, bx, bx + 8, by, by + 8);
        worst = std::max(worst, std::abs(a / b - 1));
      }
  std::printf("worst 8x8 block ratio off by %.4f\n", worst);
  // Measured: 0.0091 and 0.0061, falling as 1 / sqrt(spp) (0.0024 and 0.0021 at 8192 spp:
  // Monte Carlo noise, no bias to 0.2 %). Half a pixel's shift of the camera gives 0.043 and
  // 0.22; next-event estimation without the BSDF's 1/pi, 0.18 and 0.39.
  EXPECT_LT(rel_rmse, 0.02);
  EXPECT_LT(worst, 0.02);
}

}  // namespace
}  // namespace lp
