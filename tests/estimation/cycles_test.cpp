// Independent truth for the light's place: a scene bundle rendered by Blender Cycles
// (tests/data/cycles, 4096 spp, a point light of radius 0.1 m 1.8 m from the room's centre,
// known albedo, a held-out second view). Neither the images nor the light's position went
// through this project's renderer, so a convention error shared by the renderer and the
// estimator (a mirrored azimuth, a flipped up, a transposed pose, a factor of pi in the
// point light's units) cannot pass here as it can on self-made scenes.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/color.h"
#include "common/image_io.h"
#include "estimation/estimator.h"
#include "estimation/path_tracer.h"
#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "estimation/truth.h"
#include "estimation/truth_scorer.h"
#include "estimation/vertex_radiance.h"
#include "scene/albedo.h"
#include "scene/mesh.h"
#include "scene/scene_bundle.h"
#include "scene/surface_filter.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

Eigen::Vector3d Vec(const nlohmann::json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }

fs::path CyclesDir(const char* name) { return fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data" / "cycles" / name; }

/// The estimate's render of `bundle`'s views (map and point lights), every pixel.
std::vector<ImageRGB> Relight(const SceneBundle& bundle, const EstimateResult& r, int spp) {
  RayTracer scene(bundle.mesh);
  TracerOptions o;
  o.spp = spp;
  o.seed = 3;
  CellSampler sampler(r.env, r.lighting.map, {}, 0.2);
  std::vector<ImageRGB> out = RenderEnvironment(scene, r.env, bundle.views, r.lighting.map, sampler, o, true);
  const std::vector<ImageRGB> near = RenderLights(scene, bundle.views, AsLights(r.lighting.Of<PointLight>()), o, true);
  for (std::size_t v = 0; v < out.size(); ++v)
    for (std::size_t i = 0; i < out[v].data.size(); ++i) out[v].data[i] += near[v].data[i];
  return out;
}

TEST(Cycles, TheLampComesBackAtItsPlaceWithItsIntensity) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("cornerbox_one_light"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("cornerbox_one_light") / "truth.json"));
  const Eigen::Vector3d lamp = Vec(truth["lights"][0]["position"]);
  const Eigen::Vector3d centre = Vec(truth["scene_bbox"]["centre"]);
  const double intensity = truth["lights"][0]["radiant_intensity_rgb_W_per_sr"][0].get<double>();  // 12.73 W/sr
  const double distance = (lamp - centre).norm();  // 1.818 m

  EstimateOptions o;
  o.tracer.spp = 64;
  o.max_rounds = 3;
  o.render = false;
  o.scorer = TruthScorer::FromBundle(bundle);  // the dominant direction's error below
  const EstimateResult r = Estimate(bundle, o);
  ASSERT_EQ(r.lighting.Count<PointLight>(), 1u) << "one lamp lights this room";
  // Round 1 found it on every 2nd pixel of every 2nd row (kFirstRoundPixels), the rounds
  // after fit them all, and trace the map at a quarter of the samples: the lamp renders
  // nearly all the light.
  ASSERT_GE(r.rounds.size(), 2u);
  EXPECT_EQ(r.rounds[0].pixels, 80 * 60);
  EXPECT_EQ(r.rounds[1].pixels, r.observations);
  EXPECT_EQ(r.rounds[0].spp, 64);
  EXPECT_EQ(r.rounds[1].spp, 16);
  const PointLight l = r.lighting.Of<PointLight>()[0];
  const double error = (l.position - lamp).norm();
  std::printf("lamp at (%.3f, %.3f, %.3f), %.3f m (%.1f %% of its distance) from the truth; intensity %.3f %.3f %.3f "
              "W/sr (truth %.3f)\n",
              l.position.x(), l.position.y(), l.position.z(), error, 100 * error / distance, l.intensity.x(),
              l.intensity.y(), l.intensity.z(), intensity);
  // The targets: within 6 % of its distance from the centre (measured 2.0 %), the
  // intensity within 15 % (measured +4.5 %; Cycles' lamp is a 0.1 m disc, ours a point).
  EXPECT_LT(error, 0.06 * distance);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(l.intensity[c], intensity, 0.15 * intensity);
  // The dominant direction is the lamp's (measured 1.5 degrees).
  EXPECT_LT(r.final_angular_error_deg, 4);

  // The fitted view and a held-out one, re-rendered from the estimate: within 8 % and 10 %
  // (measured 4.7 % and 5.7 % at 128 spp; the true light through this renderer gives 4.7 % on the
  // fitted view: the disc's soft shadow edges).
  const std::vector<ImageRGB> fitted = Relight(bundle, r, 128);
  const double fit_error = RelativeImageRmse(fitted[0], bundle.views[0].image, bundle.views[0].valid);
  const SceneBundle holdout = LoadSceneBundle(CyclesDir("cornerbox_one_light_holdout"));
  const std::vector<ImageRGB> held = Relight(holdout, r, 128);
  const double held_error = RelativeImageRmse(held[0], holdout.views[0].image, holdout.views[0].valid);
  std::printf("relative RMSE: fitted view %.4f, held-out view %.4f\n", fit_error, held_error);
  EXPECT_LT(fit_error, 0.08);
  EXPECT_LT(held_error, 0.10);
}

TEST(Cycles, TheMapAloneStillPutsTheLampOnItsSide) {
  // The far-light model (--point-lights 0) on the same room: it cannot place a lamp this
  // close, but it must put its light on the lamp's side of the scene.
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("cornerbox_one_light"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("cornerbox_one_light") / "truth.json"));
  const Eigen::Vector3d to_lamp = (Vec(truth["lights"][0]["position"]) - Vec(truth["scene_bbox"]["centre"])).normalized();
  EstimateOptions o;
  o.tracer.spp = 64;
  o.max_rounds = 3;
  o.render = false;
  o.point_lights.max_lights = 0;
  o.directional_lights = false;  // the map alone (a sun is sought whatever the lamps)
  const EstimateResult r = Estimate(bundle, o);
  EXPECT_TRUE(r.lighting.Count<PointLight>() == 0);
  ASSERT_FALSE(r.dominant.empty());
  const double angle = AngleDeg(r.dominant[0], to_lamp);
  // Measured: 79 degrees from the lamp (77 at the estimate's defaults); a flipped up or a map
  // turned upside down fails these.
  EXPECT_LT(angle, 90);
  EXPECT_GT(r.dominant[0].dot(bundle.up), 0.3);
  EXPECT_LT(r.final_relative_rmse, 0.5);  // 0.365 measured
}

// Directional lights against an independent renderer: a room corner under Cycles' sun lamp
// (0.53 degrees wide, 3 W/m^2) and a sky 1000 times dimmer (tests/data/cycles/sun, made by
// scripts/make-cycles-sun.py at 1024 spp, with a held-out view): the sun's direction comes
// from the shadows Cycles drew, its irradiance from Blender's own units.
TEST(Cycles, TheSunComesBackAsADirectionalLight) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("sun"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("sun") / "truth.json"));
  const Eigen::Vector3d sun = Vec(truth["lights"][0]["direction"]).normalized();
  const double irradiance = truth["lights"][0]["irradiance_rgb_W_per_m2"][0].get<double>();  // 3 W/m^2
  EstimateOptions o;
  o.render = false;
  o.directional_lights = true;
  const EstimateResult r = Estimate(bundle, o);
  EXPECT_TRUE(r.lighting.Count<PointLight>() == 0) << "a sun is not a lamp in the room";
  ASSERT_EQ(r.lighting.Count<DirectionalLight>(), 1u);
  // Its held-out loss 0.27 of its cells' (measured): a sun, so the map's prior is not chosen
  // beside it (kDecisiveSunRatio; the flat sky's light, 0.94, is: AFlatSkyComesBackFlat).
  EXPECT_TRUE(std::isnan(r.prior.chosen)) << r.prior.why;
  EXPECT_NE(r.prior.why.find("a sun, not a flat sky"), std::string::npos) << r.prior.why;
  const DirectionalLight d = r.lighting.Of<DirectionalLight>()[0];
  const double angle = AngleDeg(d.direction, sun);
  std::printf("sun %.3f degrees from the truth, irradiance %.3f %.3f %.3f W/m^2 (truth %.3f); residual %.4f\n", angle,
              d.irradiance.x(), d.irradiance.y(), d.irradiance.z(), irradiance, r.final_relative_rmse);
  // Issue 21 asks 0.5 degrees. Measured 0.25 (5 bounces, the direction searched against the
  // map solved again until it stays; 0.59 with 3 bounces and one pass), irradiance -0.2 %.
  EXPECT_LT(angle, 0.5);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(d.irradiance[c], irradiance, 0.02 * irradiance);
  // Both views re-rendered from the estimate at 256 spp (map, lamps and suns on the same
  // paths): measured 2.8 % fitted (the true sun relit so: 2.8 %; the fit's own residual, ~10 %,
  // is its 8-spp light columns' noise) and 2.9 % held out.
  auto relit_error = [&](const SceneBundle& b) {
    const RayTracer scene(b.mesh);
    TracerOptions t;
    t.spp = 256, t.seed = 3;
    const ImageRGB im =
        RenderLighting(scene, r.env, r.lighting, CellSampler(r.env, r.lighting.map, {}, 0.2), b.views, t, true)[0];
    return RelativeImageRmse(im, b.views[0].image, b.views[0].valid);
  };
  // The sky (Blender's world, uniform, 1/1000 of the sun's irradiance facing up) is in the
  // map: its mean radiance above the horizon within 20 % of the world's (measured -14 %; on
  // the synthetic sun-and-sky the same fit is 7x too bright, lamp_recovery_test).
  double radiance = 0, solid_angle = 0;
  for (int j = 0; j < r.env.size(); ++j)
    if (r.env.direction(j).dot(bundle.up) > 0) {
      radiance += r.env.solid_angle(j) * Luminance(r.lighting.map[3 * j], r.lighting.map[3 * j + 1], r.lighting.map[3 * j + 2]);
      solid_angle += r.env.solid_angle(j);
    }
  const double world = truth["world"]["radiance"][0].get<double>();
  std::printf("sky: mean radiance above the horizon %.4g W/m^2/sr (the world's %.4g)\n", radiance / solid_angle, world);
  EXPECT_NEAR(radiance / solid_angle, world, 0.2 * world);
  const double fitted = relit_error(bundle), held = relit_error(LoadSceneBundle(CyclesDir("sun_holdout")));
  std::printf("relit relative RMSE: fitted view %.4f, held-out view %.4f\n", fitted, held);
  EXPECT_LT(fitted, 0.05);
  EXPECT_LT(held, 0.08);
}

/// `lighting` relit on `bundle`'s view at 256 spp (map, lamps and suns on the same paths),
/// its relative RMSE against the view's image over the pixels that see the mesh (where the
/// view sees the world itself, the held-out view sees directions no fitted pixel lit).
/// `whole_pixels`: only the pixels whose four corners' rays hit the mesh too (a pixel on a
/// window's edge sees the world beyond it in part, which no estimate fixes).
double RelitError(const SceneBundle& bundle, const EnvMap& env, const Lighting& lighting, bool whole_pixels = false,
                  const std::vector<std::shared_ptr<const EmitterShape>>& openings = {}) {
  const RayTracer scene(bundle.mesh, TrianglesOnShapes(bundle.mesh, openings));
  TracerOptions t;
  t.spp = 256, t.seed = 3;
  const ImageRGB im = RenderLighting(scene, env, lighting, CellSampler(env, lighting.map, {}, 0.2), bundle.views, t, true)[0];
  const Camera& cam = bundle.views[0].camera;
  std::vector<std::uint8_t> surface(static_cast<std::size_t>(cam.width) * cam.height, 0);
  const auto hits = [&](double u, double v) {
    SurfacePoint hit;
    return scene.Intersect(cam.center(), cam.RayDirection(u, v), &hit);
  };
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u)
      surface[v * cam.width + u] = hits(u, v) && (!whole_pixels || (hits(u - 0.5, v - 0.5) && hits(u + 0.5, v - 0.5) &&
                                                                   hits(u - 0.5, v + 0.5) && hits(u + 0.5, v + 0.5)));
  return RelativeImageRmse(im, bundle.views[0].image, surface);
}

/// A map of `env`'s cells all at `radiance` (Blender's uniform world, below the horizon too).
std::vector<double> UniformMap(const EnvMap& env, double radiance) { return std::vector<double>(3 * env.size(), radiance); }

/// The map's irradiance on a surface facing `up` (luminance).
double IrradianceUp(const EnvMap& env, const std::vector<double>& map, const Eigen::Vector3d& up) {
  double e = 0;
  for (int j = 0; j < env.size(); ++j)
    e += std::max(0.0, env.direction(j).dot(up)) * env.solid_angle(j) * Luminance(map[3 * j], map[3 * j + 1], map[3 * j + 2]);
  return e;
}

// Issue 42: a uniform white sky (tests/data/cycles/sky, made by scripts/make-cycles-sun.py
// KIND sky: the room corner open above and on two sides, irradiance 1 on an open floor)
// comes back flat. Under the given prior (alpha 3) the rounds take it for a sun and a lamp
// 7 m away and leave the map nearly dark; the prior the data choose (with the map alone
// beside the directional light) drops them and keeps a smooth map. The held-out view sees
// surfaces lit from below the horizon past the floor's edge, directions the fitted view
// hardly fixes: under the activation penalty alone they stayed dark or spiky and the view
// relit at 6.4 % against 3.6 % for the true sky (1.8x; alpha fixed at 0.03: 6.1 %, at 0.01:
// 5.9 %). The map smooth between neighbouring cells (chosen by the held-out blocks:
// smoothness 1000, loss 2173 against 2205 for the best sparse weight, standard error 3.3)
// fills them from their neighbours: measured 3.57 % (1.00x), the irradiance facing up -0.8 %
// (-9.5 %). Asserted: the 1.25x, 10 %; the smooth map's choice (without it: 1.8x).
TEST(Cycles, AFlatSkyComesBackFlat) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("sky"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("sky") / "truth.json"));
  const double world = truth["world"]["radiance"][0].get<double>();
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  EXPECT_TRUE(r.lighting.lights.empty()) << r.prior.why;
  EXPECT_LT(r.prior.chosen, o.objective.alpha);
  EXPECT_GT(r.prior.chosen_smooth, 0) << r.prior.why;
  int above = 0, lit = 0;
  for (int j = 0; j < r.env.size(); ++j)
    if (r.env.direction(j).dot(bundle.up) > 0) ++above, lit += r.lighting.map[3 * j] > 0;
  const double up = IrradianceUp(r.env, r.lighting.map, bundle.up), true_up = IrradianceUp(r.env, UniformMap(r.env, world), bundle.up);
  const SceneBundle held = LoadSceneBundle(CyclesDir("sky_holdout"));
  const double relit = RelitError(held, r.env, r.lighting), floor = RelitError(held, r.env, {UniformMap(r.env, world), {}});
  std::printf("flat sky: prior %g, smoothness %g (%s); %d of %d cells above the horizon lit; irradiance facing up %.4f "
              "(truth %.4f); held-out relit %.4f (the true sky %.4f)\n",
              r.prior.chosen, r.prior.chosen_smooth, r.prior.why.c_str(), lit, above, up, true_up, relit, floor);
  EXPECT_GT(lit, above / 2);
  EXPECT_NEAR(up, true_up, 0.1 * true_up);
  EXPECT_LT(relit, 1.25 * floor);
}

// Issue 42: a lamp beside a sky 1/20 as bright (tests/data/cycles/lamp_sky, KIND lamp-sky):
// the sky stays in the map (the issue asks its irradiance facing up within 20 % of the world's) and the
// lamp comes back as it does alone (within 5 % of its distance, intensity within 15 %); the
// held-out view relit within 1.25x the same render of the true lamp and sky. Measured: the
// prior 0.1, the sky -6.8 %, the lamp 0.8 cm off and -1.6 %, relit 3.19 % against 2.58 %
// (1.24x; at the given prior, --choose-prior 0, the sky comes back -37 %). That 1.25x is
// not met over seeds: estimate seeds 1-4 gave 1.24, 1.45, 1.22, 1.40x (the lamp 0.8, 1.9,
// 0.3, 1.7 cm off) at session 38's end, and 1.33, 1.38, 1.21, 1.51x (1.9, 1.3, 0.9, 1.9 cm)
// with the lamp's radius refined (session 39), so the test held 1.6x until session 41
// (docs/benchmarks.md, session 39). Nor was the sky's 20 %: over estimate seeds 1-4 it came
// back -9, -26, -11, -20 % (the lamp 1.9, 1.3, 0.9, 1.9 cm off) before the prior was chosen
// after the lamps' refinement (session 41), -26, -26, -13, -12 % (0.8, 1.3, 1.4, 0.7 cm)
// then: at alpha/10 the penalty left the sky a quarter low. With the map solved once more at
// alpha/30 beside the lamps where a weaker prior was chosen (RelaxPrior): -14.5, -11, -13,
// -12 %, and this seed's held-out view 1.19x the truth's (1.26x before; the other seeds'
// not measured): the 20 % and 1.25x held (docs/benchmarks.md, session 41).
TEST(Cycles, ADimSkyBesideALampStaysInTheMap) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("lamp_sky"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("lamp_sky") / "truth.json"));
  const double world = truth["world"]["radiance"][0].get<double>();
  const nlohmann::json& lamp = truth["lights"][0];
  const Eigen::Vector3d position = Vec(lamp["position"]), intensity = Vec(lamp["intensity_image_units"]);
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  ASSERT_EQ(r.lighting.Count<PointLight>(), 1u) << r.prior.why;
  const PointLight l = r.lighting.Of<PointLight>()[0];
  const double distance = lamp["distance_from_centre"].get<double>(), error = (l.position - position).norm();
  const double up = IrradianceUp(r.env, r.lighting.map, bundle.up), true_up = IrradianceUp(r.env, UniformMap(r.env, world), bundle.up);
  const SceneBundle held = LoadSceneBundle(CyclesDir("lamp_sky_holdout"));
  const PointLight true_lamp{position, intensity, lamp["radius"].get<double>()};
  const double relit = RelitError(held, r.env, r.lighting),
               floor = RelitError(held, r.env, {UniformMap(r.env, world), {true_lamp}});
  std::printf("lamp beside a dim sky: prior %g; lamp %.2f cm off (%.1f %% of %.2f m), intensity %.3f (truth %.3f); the "
              "sky's irradiance facing up %.4f (truth %.4f); held-out relit %.4f (the truth %.4f)\n",
              r.prior.chosen, 100 * error, 100 * error / distance, distance, l.intensity.x(), intensity.x(), up, true_up,
              relit, floor);
  EXPECT_LT(error, 0.05 * distance);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(l.intensity[c], intensity[c], 0.15 * intensity[c]);
  EXPECT_NEAR(up, true_up, 0.2 * true_up);
  EXPECT_LT(relit, 1.25 * floor);
}

// Issue 42: two lamps of different brightness and colour (tests/data/cycles/two_lamps, KIND
// two-lamps: warm 140 W 1.73 m from the corner's centre, cool 70 W 1.65 m), the true mesh
// and albedo: each within 5 % of its distance and its intensity within 15 % per channel; the
// held-out view relit within 1.25x the same render of the true lamps. Measured: warm 2.0 cm
// (1.2 %), x0.98; cool 0.4 cm (0.2 %), x1.00; relit 2.9 % against 2.7 % (1.09x). (The weaker lamp does not slide along its ray:
// LightFit.ALampStartedAnywhereAlongItsValleyEndsAtOneMinimum.)
TEST(Cycles, TwoLampsOfDifferentBrightnessComeBackEach) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("two_lamps"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("two_lamps") / "truth.json"));
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  const std::vector<PointLight> found = r.lighting.Of<PointLight>();
  ASSERT_EQ(found.size(), 2u);
  std::vector<PointLight> true_lamps;
  for (const nlohmann::json& lamp : truth["lights"]) {
    const Eigen::Vector3d position = Vec(lamp["position"]), intensity = Vec(lamp["intensity_image_units"]);
    true_lamps.push_back({position, intensity, lamp["radius"].get<double>()});
    const PointLight& l = *std::min_element(found.begin(), found.end(), [&](const PointLight& a, const PointLight& b) {
      return (a.position - position).norm() < (b.position - position).norm();
    });
    const double distance = lamp["distance_from_centre"].get<double>(), error = (l.position - position).norm();
    std::printf("%s lamp: %.2f cm off (%.1f %% of %.2f m), intensity %.3f %.3f %.3f (truth %.3f %.3f %.3f)\n",
                lamp["name"].get<std::string>().c_str(), 100 * error, 100 * error / distance, distance, l.intensity.x(),
                l.intensity.y(), l.intensity.z(), intensity.x(), intensity.y(), intensity.z());
    EXPECT_LT(error, 0.05 * distance) << lamp["name"];
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(l.intensity[c], intensity[c], 0.15 * intensity[c]) << lamp["name"] << " channel " << c;
  }
  const SceneBundle held = LoadSceneBundle(CyclesDir("two_lamps_holdout"));
  const double relit = RelitError(held, r.env, r.lighting), floor = RelitError(held, r.env, {UniformMap(r.env, 0), AsLights(true_lamps)});
  std::printf("two lamps: held-out relit %.4f (the true lamps %.4f)\n", relit, floor);
  EXPECT_LT(relit, 1.25 * floor);
}

// Issue 42: a real HDR world (tests/data/cycles/hdr, KIND hdr: Poly Haven's studio_small_03,
// small bright softboxes, CC0, as lightprobe reads the equirect), both views masked to the
// pixels that see the room (mask0.png): the held-out view relit within 1.25x the same render
// (256 spp) of the true world on a fine grid (91 rings, ~2 degree cells). Measured: a
// directional light kept for the main softbox, alpha 3; relit 4.85 % against 7.3 % (0.66x;
// at 1024 spp 3.4 % against 3.95 %, 0.87x: the small bright softboxes are noisy to render);
// the true world on the estimate's 522 cells 10.2 % (they smear the softboxes' shadows, the
// directional light keeps them sharp).
TEST(Cycles, AnHdrWorldRelightsWithinTheTruthsError) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("hdr"));
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  const ImageRGB hdr = ReadHdr(fs::path(LIGHTPROBE_SOURCE_DIR) / "assets" / "hdri" / "studio_small_03_1k.hdr");
  const SceneBundle held = LoadSceneBundle(CyclesDir("hdr_holdout"));
  const EnvMap fine(91, bundle.up);  // ~2 degree cells, as synth renders a measured map
  const double relit = RelitError(held, r.env, r.lighting), floor = RelitError(held, fine, {fine.FromEquirect(hdr, 64), {}}),
               on_cells = RelitError(held, r.env, {r.env.FromEquirect(hdr), {}});
  std::printf("HDR world: prior %g, %zu directional and %zu point light(s); held-out relit %.4f (the true world %.4f: "
              "%.2fx; on the estimate's cells %.4f)\n",
              r.prior.chosen, r.lighting.Count<DirectionalLight>(), r.lighting.Count<PointLight>(), relit, floor,
              relit / floor, on_cells);
  EXPECT_LT(relit, 1.25 * floor);
}

// Issue 43: a lamp in its shade (tests/data/cycles/shade, KIND shade: a 40 W bulb inside a
// 16-sided open band of radius 15 cm that lets 0.7 / 0.65 / 0.55 of what reaches it through,
// reflecting nothing; two fitted views, from either side, as a scan sees it): the band comes
// back as an emitter and the lamp inside it (moved there from below the shade, where the
// shading first put it, because the objective and the held-out pixels say so, and kept
// though its own light through the openings is a tenth of what is seen: a bulb and its
// shade are one light). Measured: the lamp 0.6 cm off; the emitter 0.161 m^2 of the band's
// 0.234 (the views see its outside, not its top and bottom rims), its radiance 19.6 (green;
// the band's mean 19.4).
TEST(Cycles, ALampInItsGlowingShadeIsFoundInsideIt) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("shade"));
  const fs::path truth_file = CyclesDir("shade") / "truth.json";
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(truth_file));
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  const std::vector<PointLight> lamps = r.lighting.Of<PointLight>();
  const std::vector<EmitterLight> found = r.lighting.Of<EmitterLight>(),
                                  shade = ParseTruthEmitters(ReadTextFile(truth_file), truth_file.string());
  ASSERT_EQ(lamps.size(), 1u);
  ASSERT_EQ(found.size(), 1u);
  const Eigen::Vector3d bulb = Vec(truth["lights"][0]["position"]);
  const double overlap = found[0].Area() * AreaOn(*found[0].shape, *shade[0].shape),
               iou = overlap / (found[0].Area() + shade[0].Area() - overlap);
  std::printf("lamp %.2f cm from the bulb; emitter %.3f m^2 (IoU %.2f with the band), radiance %.2f %.2f %.2f (the "
              "band's mean %.2f %.2f %.2f), power x%.2f\n",
              100 * (lamps[0].position - bulb).norm(), found[0].Area(), iou, found[0].radiance.x(),
              found[0].radiance.y(), found[0].radiance.z(), shade[0].radiance.x(), shade[0].radiance.y(),
              shade[0].radiance.z(), found[0].Power().sum() / shade[0].Power().sum());
  EXPECT_LT((lamps[0].position - bulb).norm(), 0.05);
  EXPECT_GT(iou, 0.6);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(found[0].radiance[c], shade[0].radiance[c], 0.15 * shade[0].radiance[c]) << c;
}

// Issue 43: an open window (tests/data/cycles/open_window, KIND open-window: a 0.8 x 0.8 m
// hole in a wall, the world bright (radiance 2) only behind that wall, directions with x <
// -0.3; both views masked to the room, as a scan has no depth through a window): the light
// comes through the opening with its direction, so it is the map's, not a glowing surface's
// nor a lamp's; the held-out view relit within 1.25x the same render of the true world on a
// fine grid (91 rings), over the pixels that see the room whole (those on the window's edge
// see the world beyond it in part, directions no view fixes), and most of the map's light
// from behind the wall.
TEST(Cycles, AnOpenWindowsLightComesBackInTheMap) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("open_window"));
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  EXPECT_EQ(r.lighting.Count<PointLight>(), 0u);
  EXPECT_EQ(r.lighting.Count<EmitterLight>(), 0u);
  const EnvMap fine(91, bundle.up);
  std::vector<double> world(3 * fine.size(), 0.0);
  for (int j = 0; j < fine.size(); ++j)
    if (fine.direction(j).x() < -0.3) world[3 * j] = world[3 * j + 1] = world[3 * j + 2] = 2.0;
  double behind = 0, all = 0;  // the map's power (luminance x solid angle), and behind the wall
  for (int j = 0; j < r.env.size(); ++j) {
    const double p = Luminance(r.lighting.map[3 * j], r.lighting.map[3 * j + 1], r.lighting.map[3 * j + 2]) *
                     r.env.solid_angle(j);
    all += p;
    behind += r.env.direction(j).x() < 0 ? p : 0.0;
  }
  const SceneBundle held = LoadSceneBundle(CyclesDir("open_window_holdout"));
  const double relit = RelitError(held, r.env, r.lighting, true), floor = RelitError(held, fine, {world, {}}, true);
  std::printf("open window: prior %g, %zu directional light(s), %.0f %% of the map's power behind the wall; held-out "
              "relit %.4f (the true world %.4f: %.2fx)\n",
              r.prior.chosen, r.lighting.Count<DirectionalLight>(), 100 * behind / all, relit, floor, relit / floor);
  EXPECT_GT(behind, 0.8 * all);
  EXPECT_LT(relit, 1.25 * floor);
}

// Issue 43: a window's clear glass that the depth camera saw (tests/data/cycles/glazed_window,
// made by scripts/make-cycles-sun.py KIND glazed-window): Cycles renders the open window's
// room with nothing in the hole and a world bright only in a cone of 37 degrees about -x,
// whose light comes through the hole as a beam; the bundle's mesh has a pane in the hole and
// the views see it. Its pixels glow, but a glowing pane lights the room everywhere it faces
// and a plain one blocks the beam: the data chooses the opening (the map seen through it),
// and the held-out view is relit through it as under the true world.
TEST(Cycles, AClearWindowTheDepthCameraSawComesBackAsAnOpening) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("glazed_window"));
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  ASSERT_EQ(r.openings.size(), 1u);
  EXPECT_EQ(r.lighting.Count<EmitterLight>(), 0u);
  EXPECT_EQ(r.lighting.Count<PointLight>(), 0u);
  EXPECT_NEAR(r.openings[0]->area, 0.64, 0.03);  // the 0.8 x 0.8 m pane
  const EnvMap fine(91, bundle.up);
  std::vector<double> world(3 * fine.size(), 0.0);
  for (int j = 0; j < fine.size(); ++j)
    if (fine.direction(j).x() < -0.8) world[3 * j] = world[3 * j + 1] = world[3 * j + 2] = 4.0;
  const SceneBundle held = LoadSceneBundle(CyclesDir("glazed_window_holdout"));
  // Both through the opening, over the pixels that see the room whole (not through the hole).
  const double relit = RelitError(held, r.env, r.lighting, true, r.openings),
               floor = RelitError(held, fine, {world, {}}, true, r.openings);
  // ... and as the pane would have it: the true world's light blocked where the glass is.
  const double as_pane = RelitError(held, r.env, r.lighting, true);
  std::printf("glazed window: %zu opening(s) of %.3f m^2, %zu emitter(s); held-out relit %.4f (the true world %.4f: "
              "%.2fx; with the pane in place %.4f)\n",
              r.openings.size(), r.openings[0]->area, r.lighting.Count<EmitterLight>(), relit, floor, relit / floor,
              as_pane);
  // Measured 0.349 against the true world's 0.342 (1.02x; 1.02-1.09x over the tracer's seeds
  // 1-5), and 3.90 with the pane in place. Before the prior of the cells behind an opening was
  // the least held-out loss's and its rounds ran until the map settled: 0.736 (2.15x), the
  // sparse prior keeping a quarter of the cone's power (docs/method.md, "Windows").
  EXPECT_LT(relit, 1.25 * floor);
  EXPECT_GT(as_pane, 3 * relit);
}

/// A window whose glass returned no depth, made from a bundle that has its pane: the
/// triangles the first view's pixels brighter than luminance 2 see (the pane) cut out of the
/// mesh, and every pixel that then sees no mesh invalid (no depth), the bright ones clipped
/// off the mesh, as a scan's would be. Returns the pane's triangles; `with_pane` the mesh
/// before.
std::vector<int> CutThePaneOut(SceneBundle* bundle, Mesh* with_pane) {
  View& v = bundle->views[0];
  const Camera& cam = v.camera;
  std::vector<std::uint8_t> pane(bundle->mesh.triangles.size(), 0);
  {
    const RayTracer scene(bundle->mesh);
    for (std::size_t p = 0; p < v.valid.size(); ++p) {
      const float* c = v.image.at(static_cast<int>(p % cam.width), static_cast<int>(p / cam.width));
      SurfacePoint hit;
      if (Luminance(c[0], c[1], c[2]) > 2 &&
          scene.Intersect(cam.center(), cam.RayDirection(double(p % cam.width), double(p / cam.width)), &hit))
        pane[hit.triangle] = 1;
    }
  }
  std::vector<int> pane_triangles;
  for (std::size_t t = 0; t < pane.size(); ++t)
    if (pane[t]) pane_triangles.push_back(static_cast<int>(t));
  *with_pane = bundle->mesh;
  bundle->mesh = WithoutTriangles(*with_pane, pane);
  const RayTracer holed(bundle->mesh);
  v.clipped_off.assign(v.valid.size(), 0);
  for (std::size_t p = 0; p < v.valid.size(); ++p) {
    SurfacePoint hit;
    if (holed.Intersect(cam.center(), cam.RayDirection(double(p % cam.width), double(p / cam.width)), &hit)) continue;
    const float* c = v.image.at(static_cast<int>(p % cam.width), static_cast<int>(p / cam.width));
    v.valid[p] = 0;
    if (Luminance(c[0], c[1], c[2]) > 2) v.clipped_off[p] = 1;
  }
  return pane_triangles;
}

/// The light the estimate's map sends into the room through its one seen window.
Eigen::Vector3d LightThroughTheWindow(const EstimateResult& r) {
  Portal p;
  if (r.windows.size() != 1 || !PortalOf(r.windows[0], r.env.up(), &p)) return Eigen::Vector3d::Constant(-1);
  return PowerThrough(p, r.windows[0].normal, r.env, r.lighting.map);
}

/// The clipped pixels off the mesh of a bundle's first view.
int ClippedOff(const SceneBundle& bundle) {
  return static_cast<int>(std::count(bundle.views[0].clipped_off.begin(), bundle.views[0].clipped_off.end(), 1));
}

// Issue 43: the same window when the glass returns no depth (a hole in the wall, its pixels
// clipped), as a structured-light camera sees clear glass: the hole seen as a window before
// round 1 (SeenWindows), its cells at the weakest prior until the choice and the map's next
// events aimed through it (a portal), no lamp and no glowing surface kept in the room, and
// the held-out view relit as well as the true world's light through the hole.
TEST(Cycles, AClearWindowSeenAsAHoleLetsTheMapLightTheRoom) {
  SceneBundle bundle = LoadSceneBundle(CyclesDir("glazed_window"));
  Mesh with_pane;
  const std::vector<int> pane_triangles = CutThePaneOut(&bundle, &with_pane);
  ASSERT_GE(pane_triangles.size(), 1u);
  const int clipped = ClippedOff(bundle);
  ASSERT_GT(clipped, 100);
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  const bool seen = std::any_of(r.point_light_choices.begin(), r.point_light_choices.end(), [](const std::string& c) {
    return c.find("a window the cameras saw as a hole") != std::string::npos;
  });
  EXPECT_TRUE(seen);
  EXPECT_EQ(r.lighting.Count<PointLight>(), 0u);
  EXPECT_EQ(r.lighting.Count<EmitterLight>(), 0u);
  const EnvMap fine(91, bundle.up);
  std::vector<double> world(3 * fine.size(), 0.0);
  for (int j = 0; j < fine.size(); ++j)
    if (fine.direction(j).x() < -0.8) world[3 * j] = world[3 * j + 1] = world[3 * j + 2] = 4.0;
  const SceneBundle held = LoadSceneBundle(CyclesDir("glazed_window_holdout"));
  const std::vector<std::shared_ptr<const EmitterShape>> hole = {MakeEmitterShape(
      with_pane, pane_triangles, std::vector<Eigen::Vector3f>(pane_triangles.size(), Eigen::Vector3f::UnitX()))};
  const double relit = RelitError(held, r.env, r.lighting, true, hole), floor = RelitError(held, fine, {world, {}}, true, hole);
  const Eigen::Vector3d power = LightThroughTheWindow(r), true_power = PowerThrough(PortalOf(*hole[0], bundle.up),
                                                                                    Eigen::Vector3d::UnitX(), fine, world);
  // Measured: no lamp, no emitter (the pane over the hole left out), 0.91-0.98x; at 73bf88c (the
  // hole's extent its blob's pixel bounds, no pane tried) 0.98x (0.92-1.01x over the
  // tracer's seeds 2-5); at 0149ae9 (the hole seen after round 1, no portals) two lamps,
  // 0.98x. The light through the hole (printed) is 0.6x the true world's: the cells whose
  // light falls where no view looks are the prior's, not the data's.
  std::printf("glazed window as a hole: %d clipped pixels, %zu pane triangle(s); %zu lamp(s), %zu emitter(s), prior %g; "
              "held-out relit %.4f (the true world %.4f: %.2fx); the light through it %.3f (truth %.3f)\n",
              clipped, pane_triangles.size(), r.lighting.Count<PointLight>(), r.lighting.Count<EmitterLight>(),
              r.prior.chosen, relit, floor, relit / floor, power.x(), true_power.x());
  EXPECT_LT(relit, 1.25 * floor);
}

// Issue 43: a frosted pane whose glass returned no depth (the Cycles frosted window, KIND
// glow, cut out as above) glows as a pane over the hole (PanesOverHoles). The map behind a
// hole holds a diffuse pane only where the directions out through it reach the room no other
// way; this room is open above its 1.6 m walls, and without the pane candidate the map alone
// fitted at 0.89 relative error and round 1 kept two lamps at the wall (held-out 4.6x).
// The pane found over the hole (IoU >= 0.7), the light through it within 15 % of the true
// pane's power, no lamp, and the held-out view relit within 1.25x the true pane's error.
// Measured: IoU 1.00, radiance 3.03 / 2.72 / 2.27 (truth 3 / 2.7 / 2.25), 1.00x.
TEST(Cycles, AFrostedWindowSeenAsAHoleGlowsAsAPane) {
  SceneBundle bundle = LoadSceneBundle(CyclesDir("glow"));
  Mesh with_pane;
  const std::vector<int> pane_triangles = CutThePaneOut(&bundle, &with_pane);
  ASSERT_GE(pane_triangles.size(), 1u);
  ASSERT_GT(ClippedOff(bundle), 100);
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  ASSERT_EQ(r.windows.size(), 1u);
  EXPECT_EQ(r.lighting.Count<PointLight>(), 0u);
  const fs::path truth_file = CyclesDir("glow") / "truth.json";
  const std::vector<EmitterLight> pane = ParseTruthEmitters(ReadTextFile(truth_file), truth_file.string());
  ASSERT_EQ(pane.size(), 1u);
  const std::vector<EmitterLight> found = r.lighting.Of<EmitterLight>();
  ASSERT_EQ(found.size(), 1u);
  EXPECT_TRUE(found[0].in_a_hole);
  const double on_pane = AreaOn(*found[0].shape, *pane[0].shape), overlap = found[0].Area() * on_pane,
               iou = overlap / (found[0].Area() + pane[0].Area() - overlap);
  std::printf("the pane over the hole: %.3f m^2, IoU %.2f, radiance %.3f %.3f %.3f\n", found[0].Area(), iou,
              found[0].radiance.x(), found[0].radiance.y(), found[0].radiance.z());
  EXPECT_GE(iou, 0.7);
  const Eigen::Vector3d power = LightThroughTheWindow(r) + found[0].Power(), true_power = pane[0].Power();
  const std::vector<std::shared_ptr<const EmitterShape>> hole = {MakeEmitterShape(
      with_pane, pane_triangles, std::vector<Eigen::Vector3f>(pane_triangles.size(), Eigen::Vector3f::UnitX()))};
  const SceneBundle held = LoadSceneBundle(CyclesDir("glow_holdout"));
  const double relit = RelitError(held, r.env, r.lighting, true, hole),
               floor = RelitError(held, r.env, {UniformMap(r.env, 0), AsLights(pane)}, true, hole);
  std::printf("frosted window as a hole: %zu lamp(s), %zu emitter(s), prior %g; the light through it %.3f %.3f %.3f "
              "(the pane's %.3f %.3f %.3f); held-out relit %.4f (the true pane %.4f: %.2fx)\n",
              r.lighting.Count<PointLight>(), r.lighting.Count<EmitterLight>(), r.prior.chosen, power.x(), power.y(),
              power.z(), true_power.x(), true_power.y(), true_power.z(), relit, floor, relit / floor);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(power[c], true_power[c], 0.15 * true_power[c]) << "channel " << c;
  EXPECT_LT(relit, 1.25 * floor);
  if (::testing::Test::HasFailure())
    for (const std::string& c : r.point_light_choices) std::printf("  %s\n", c.c_str());
}

// The albedo passes de-light the colours seen by every light the fit uses, a glowing
// surface's too: Cycles' frosted window (KIND glow; the room lit by its pane alone) with its
// mesh made to look reconstructed (refined to 30000 triangles, the colours seen the true
// albedo times what the true pane sends each vertex, flattened into segments). The refined
// albedo's spread about the truth (mean |log| of its ratio to the true albedo about their
// median ratio) falls well under the flattened colours'.
TEST(Cycles, TheAlbedoPassDividesTheGlowingPanesLightOut) {
  SceneBundle bundle = LoadSceneBundle(CyclesDir("glow"));
  const fs::path truth_file = CyclesDir("glow") / "truth.json";
  const std::vector<EmitterLight> pane = ParseTruthEmitters(ReadTextFile(truth_file), truth_file.string());
  bundle.mesh = RefineMesh(bundle.mesh, 30000);
  const std::vector<Eigen::Vector3f> true_albedo = bundle.mesh.albedo;
  const EnvMap env(9, bundle.up);
  {
    const RayTracer scene(bundle.mesh);
    VertexRadiance seen(scene, env, {UniformMap(env, 0), AsLights(pane)}, 4, 5);
    seen.Refine(128);
    bundle.mesh.shaded = seen.Radiance();
  }
  bundle.mesh.albedo = bundle.mesh.shaded;
  FlattenAlbedo(&bundle.mesh);
  const auto spread = [&](const std::vector<Eigen::Vector3f>& a) {
    std::vector<double> r;
    for (std::size_t v = 0; v < a.size(); ++v)
      if (bundle.mesh.shaded[v].sum() > 1e-3 && true_albedo[v].sum() > 1e-3)
        r.push_back(std::log(std::max(1e-6f, a[v].sum()) / true_albedo[v].sum()));
    std::vector<double> sorted = r;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    double e = 0;
    for (double x : r) e += std::abs(x - sorted[sorted.size() / 2]);
    return e / r.size();
  };
  const double flattened = spread(bundle.mesh.albedo);
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  ASSERT_GE(r.albedo_passes, 1);
  ASSERT_EQ(r.lighting.Count<EmitterLight>(), 1u);
  const double refined = spread(r.albedo);
  std::printf("the frosted window's room made to look reconstructed: the albedo's spread about the truth flattened %.4f, "
              "refined %.4f (%d pass(es)); %zu lamp(s)\n",
              flattened, refined, r.albedo_passes, r.lighting.Count<PointLight>());
  EXPECT_LT(refined, 0.5 * flattened);
}

// Issue 44: render_view* is a clean render of the estimate, not the fit (whose 24 samples per
// pixel and 16-path lamp columns left the Cycles cornerbox's render_view0 10.8 % from a
// 2048-spp render of the same lights). Against an independent reference of the same
// lighting (ProgressiveRender to 960 samples, other seeds): the clean render within 3 %
// and under a third of the fit's difference, and the noise each reports honest: their
// difference's RMS within 0.7-1.4x the root of the sum of their reported noises' squares
// (measured: clean 960 spp, noise 1.66 %; see the printed line).
TEST(Cycles, TheCleanRenderIsFreeOfVisibleNoiseAndSaysHowNoisyItIs) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("cornerbox_one_light"));
  EstimateOptions o;
  // The noise asked by default (0.7 %; denoised: about 300 spp), with the time for it whatever
  // the machine's load (by default the clean render takes as long as the estimate did).
  o.render_seconds = 60;
  const EstimateResult r = Estimate(bundle, o);
  ASSERT_EQ(r.renders.size(), 1u);
  ASSERT_EQ(r.fits.size(), 1u);
  ASSERT_FALSE(r.render_passes.empty());
  EXPECT_LE(r.render_passes.back().noise, EstimateOptions{}.render_noise);
  for (std::size_t k = 1; k < r.render_passes.size(); ++k)  // each pass adds samples and lowers the noise
    EXPECT_LT(r.render_passes[k].noise, r.render_passes[k - 1].noise);
  const RayTracer scene(bundle.mesh);
  TracerOptions t;
  t.spp = 32, t.seed = 77;
  std::vector<RenderPass> passes;
  const ImageRGB reference = ProgressiveRender(scene, r.env, r.lighting, CellSampler(r.env, r.lighting.map, {}, 0.2),
                                               bundle.views, t, 0, 1e9, 1024, &passes)[0];
  const std::vector<std::uint8_t>& valid = bundle.views[0].valid;
  const double clean = RelativeImageRmse(r.renders[0], reference, valid), fit = RelativeImageRmse(r.fits[0], reference, valid);
  const double expected = std::hypot(r.render_passes.back().noise, passes.back().noise);
  std::printf("clean render (%d spp, noise %.4f) against a %d-spp reference (noise %.4f): %.4f (expected %.4f); the fit "
              "%.4f\n",
              r.render_passes.back().spp, r.render_passes.back().noise, passes.back().spp, passes.back().noise, clean,
              expected, fit);
  EXPECT_LT(clean, 0.03);
  EXPECT_LT(clean, fit / 3);
  EXPECT_GT(clean, 0.7 * expected);
  // Within 10 %: the denoiser's bias is small against its noise (smoothing across the lamp's
  // shadow edges made it 1.16x).
  EXPECT_LT(clean, 1.1 * expected);
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
// Issue 44: the clean render's denoiser against an independent renderer. Its direct light
// comes from the guide and the rest is traced without it (render_denoise.h): a convention
// the two parts got wrong between them (the light counted twice or not at all, the albedo's
// 1/pi, the sphere lamp's penumbra) would pass every test against our own renders. The
// Cycles lamp beside a dim sky (a sphere lamp: soft shadows), relit with its true lights on
// its true mesh and albedo: the denoised clean render (896 samples) is at least as close to
// Cycles' image (4096 samples) as our plain render at 1024, and its 8x8 blocks (over the
// image's mean) within half a percent of the plain render's worst. Measured: 0.84 % and
// 1.21 % against 1.31 % and 0.91 %. (At 128 samples the blocks are 1.5 % off: the denoised
// noise is shared over a window, so a block's mean does not average it down.)
TEST(Cycles, TheDenoisedCleanRenderAgreesWithCycles) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("lamp_sky"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("lamp_sky") / "truth.json"));
  const nlohmann::json& lamp = truth["lights"][0];
  const EnvMap env(9, bundle.up);
  const Lighting lighting{UniformMap(env, truth["world"]["radiance"][0].get<double>()),
                          {PointLight{Vec(lamp["position"]), Vec(lamp["intensity_image_units"]), lamp["radius"].get<double>()}}};
  const RayTracer scene(bundle.mesh);
  const CellSampler sampler(env, lighting.map, {}, 0.2);
  TracerOptions t;
  t.spp = 64, t.seed = 9;
  std::vector<RenderPass> passes;
  const ImageRGB denoised = ProgressiveRender(scene, env, lighting, sampler, bundle.views, t, 0, 1e9, 1024, &passes, {}, true)[0];
  t.spp = 1024, t.seed = 10;
  const ImageRGB plain = RenderLighting(scene, env, lighting, sampler, bundle.views, t, true)[0];
  const ImageRGB& cycles = bundle.views[0].image;
  const std::vector<std::uint8_t> all(cycles.pixels(), 1);
  const double e_denoised = RelativeImageRmse(denoised, cycles, all), e_plain = RelativeImageRmse(plain, cycles, all);
  // Each 8x8 block's mean against Cycles', over the image's mean (per channel): the noise of
  // both averages down, a bias does not.
  const auto worst_block = [&](const ImageRGB& im) {
    double worst = 0;
    for (int c = 0; c < 3; ++c) {
      const double mean = BlockMean(cycles, c, 0, im.width, 0, im.height);
      for (int by = 0; by + 8 <= im.height; by += 8)
        for (int bx = 0; bx + 8 <= im.width; bx += 8)
          worst = std::max(worst, std::abs(BlockMean(im, c, bx, bx + 8, by, by + 8) - BlockMean(cycles, c, bx, bx + 8, by, by + 8)) / mean);
    }
    return worst;
  };
  const double b_denoised = worst_block(denoised), b_plain = worst_block(plain);
  std::printf("against Cycles: the denoised clean render (%d spp, noise said %.4f) %.4f, worst 8x8 block %.4f; our plain "
              "%d-spp render %.4f, worst block %.4f\n",
              passes.back().spp, passes.back().noise, e_denoised, b_denoised, t.spp, e_plain, b_plain);
  EXPECT_LT(e_denoised, 1.1 * e_plain);
  EXPECT_LT(b_denoised, b_plain + 0.005);
}

// The viewer's lit mesh (VertexRadiance, its first bounce stratified, Clean: the sun's light
// at each vertex as traced, the rest fitted over the surface) against an independent
// renderer: Cycles' room corner under its sun and dim sky with the true lights, the mesh
// refined to a vertex every few centimetres, each vertex the view sees against Cycles' pixel
// there (where the 3 x 3 pixels around it are flat within 5 %: a pixel is an area, a vertex a
// point). Our own references share our conventions; Cycles does not.
TEST(Cycles, TheLitMeshAgreesWithCycles) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("sun"));
  const nlohmann::json truth = nlohmann::json::parse(ReadTextFile(CyclesDir("sun") / "truth.json"));
  const EnvMap env(9, bundle.up);
  DirectionalLight sun;  // sharp: the 0.53-degree disc's penumbra is a pixel or less here
  sun.direction = Vec(truth["lights"][0]["direction"]).normalized();
  sun.irradiance = Vec(truth["lights"][0]["irradiance_rgb_W_per_m2"]);
  const Lighting lighting{UniformMap(env, truth["world"]["radiance"][0].get<double>()), {sun}};
  const RayTracer scene(RefineMesh(bundle.mesh, 40000));
  const auto lit = [&](int samples, double* noise) {
    VertexRadiance vr(scene, env, lighting, 8, 3);
    vr.SetStratified(true);
    vr.Refine(samples);
    const LitShading clean = vr.Clean(SurfaceFilter{});
    *noise = clean.noise;
    return clean.radiance;
  };
  const View& view = bundle.views[0];
  const Camera& cam = view.camera;
  const ImageRGB& cycles = view.image;
  const auto compare = [&](const std::vector<Eigen::Vector3f>& radiance, double* median, int* used) {
    std::vector<double> ratios;
    double e2 = 0;
    for (std::size_t v = 0; v < radiance.size(); ++v) {
      const Eigen::Vector3d p = scene.mesh().positions[v].cast<double>();
      double u, w;
      if (!cam.Project(p, &u, &w)) continue;
      const int x = static_cast<int>(std::lround(u)), y = static_cast<int>(std::lround(w));
      if (x < 1 || y < 1 || x + 1 >= cam.width || y + 1 >= cam.height) continue;
      const Eigen::Vector3d to = p - cam.center();
      SurfacePoint hit;
      if (scene.Intersect(cam.center(), to.normalized(), &hit) && hit.distance < 0.98 * to.norm()) continue;
      float lo = 1e30f, hi = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const float g = cycles.data[3 * ((y + dy) * cycles.width + x + dx) + 1];
          lo = std::min(lo, g);
          hi = std::max(hi, g);
        }
      if (!(lo > 0) || hi > 1.05f * lo) continue;
      const double r = radiance[v].y() / cycles.data[3 * (y * cycles.width + x) + 1];
      ratios.push_back(r);
      e2 += (r - 1) * (r - 1);
    }
    *used = static_cast<int>(ratios.size());
    std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
    *median = ratios[ratios.size() / 2];
    return std::sqrt(e2 / ratios.size());
  };
  double noise = 0, median = 0;
  int used = 0;
  const double rms = compare(lit(64, &noise), &median, &used);
  std::printf("the lit mesh against Cycles at %d vertices: median ratio %.4f, RMS %.4f (noise said %.4f)\n", used, median,
              rms, noise);
  // Measured: 23,384 vertices, median 0.998, RMS 3.6 % with 3.4 % of noise said (at 256
  // samples 0.9995 and 2.5 %). The sun's light counted twice (traced and added back) or a
  // factor of pi lost moves the median by 2x or 3x.
  EXPECT_GT(used, 500);
  EXPECT_NEAR(median, 1, 0.015);
  EXPECT_LT(rms, 0.05);
}

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

// What the bounce cap costs in light, against an independent renderer's scene: the brightest
// interreflecting scene we have (the Cycles box, albedo 0.79, white sky; Cycles rendered it
// with 64 diffuse bounces). Mean at 512 spp against Cycles': cap 3 0.9898, 4 0.9953, 5 0.9977,
// 8 0.9996, 12 and 64 0.9999 (rays +3.5 % from 3 to 64: most paths end by roulette or escape).
// `render`'s cap (8) and the estimator's (5) must lose under 0.5 % against a cap of 64, and a
// cap of 3 more (a test that the cap is what cuts the light).
TEST(Cycles, TheBounceCapLosesLittleLight) {
  const SceneBundle bundle = LoadSceneBundle(CyclesDir("interreflection"));
  const RayTracer scene(bundle.mesh);
  const EnvMap env(9, bundle.up);
  const std::vector<double> white(3 * env.size(), 1.0);
  auto mean = [&](int bounces) {
    TracerOptions t;
    t.spp = 512;
    t.seed = 5;
    t.bounces = bounces;
    const ImageRGB im = RenderEnvironment(scene, env, bundle.views, white, CellSampler(env, white, {}, 0.05), t, true)[0];
    double m = 0;
    for (float v : im.data) m += v;
    return m / im.data.size();
  };
  // The same seed and paths: the renders differ only in the paths the cap cuts.
  const double far = mean(64), render = mean(kRenderBounces), estimator = mean(TracerOptions{}.bounces),
               three = mean(3);
  std::printf("cap %d / cap 64: %.5f; cap %d / cap 64: %.5f; cap 3 / cap 64: %.5f\n", kRenderBounces, render / far,
              TracerOptions{}.bounces, estimator / far, three / far);
  for (double share : {render / far, estimator / far}) {
    EXPECT_GT(share, 0.995);
    EXPECT_LE(share, 1.0 + 1e-9);
  }
  EXPECT_LT(three / far, 0.995);
}



/// Issue 43's targets on a Cycles scene lit only by one glowing surface (`name`, with the
/// true mesh and albedo): one emitter on it (its area overlapping the truth's by intersection
/// over union >= 0.7), its power within 15 %, no lamp, and the held-out view relit within
/// 1.25x the same render under the true emitter.
void ExpectTheGlowingSurface(const std::string& name) {
  const char* dir = name.c_str();
  const std::string held_name = name + "_holdout";
  const SceneBundle bundle = LoadSceneBundle(CyclesDir(dir));
  const fs::path truth_file = CyclesDir(dir) / "truth.json";
  EstimateOptions o;
  o.render = false;
  const EstimateResult r = Estimate(bundle, o);
  const std::vector<EmitterLight> found = r.lighting.Of<EmitterLight>(), pane = ParseTruthEmitters(ReadTextFile(truth_file), truth_file.string());
  ASSERT_EQ(found.size(), 1u);
  ASSERT_EQ(pane.size(), 1u);
  const double on_pane = AreaOn(*found[0].shape, *pane[0].shape), covered = AreaOn(*pane[0].shape, *found[0].shape);
  const double overlap = found[0].Area() * on_pane, iou = overlap / (found[0].Area() + pane[0].Area() - overlap);
  const Eigen::Vector3d power = found[0].Power(), true_power = pane[0].Power();
  std::printf("emitter: %.3f m^2 (%.0f %% on the truth, %.0f %% of it covered, IoU %.2f), power %.3f %.3f %.3f "
              "(truth %.3f %.3f %.3f)\n", found[0].Area(), 100 * on_pane, 100 * covered, iou, power.x(), power.y(),
              power.z(), true_power.x(), true_power.y(), true_power.z());
  EXPECT_GE(iou, 0.7);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(power[c], true_power[c], 0.15 * true_power[c]) << "channel " << c;
  for (std::size_t k = 0; k < r.lighting.lights.size(); ++k)
    if (std::holds_alternative<PointLight>(r.lighting.lights[k])) ADD_FAILURE() << "a lamp where there is none";
  const SceneBundle held = LoadSceneBundle(CyclesDir(held_name.c_str()));
  const double relit = RelitError(held, r.env, r.lighting),
               floor = RelitError(held, r.env, {UniformMap(r.env, 0), AsLights(pane)});
  std::printf("%s: held-out relit %.4f (the true emitter %.4f)\n", name.c_str(), relit, floor);
  EXPECT_LT(relit, 1.25 * floor);
}

// Issue 43: a frosted window (tests/data/cycles/glow, KIND glow: a 0.8 x 0.8 m pane in a wall
// that glows at radiance (3, 2.7, 2.25), no other light). Measured: area 0.64 m^2 (the
// pane's), radiance x1.000 / 1.000 / 1.000, no lamp (the lamp the rounds before it placed was
// dropped).
TEST(Cycles, AGlowingPaneComesBackAsAnEmitter) { ExpectTheGlowingSurface("glow"); }

// A screen (KIND screen: a dark 0.8 x 0.45 m panel, albedo 0.007, in the other wall, glowing
// bluish at (1.0, 1.3, 1.8)): a surface that reflects almost nothing, seen bright.
TEST(Cycles, AScreenComesBackAsAnEmitter) { ExpectTheGlowingSurface("screen"); }

}  // namespace
}  // namespace lp
