// End to end on synthetic scenes lit by spherical area lights (not the env-map model).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "common/color.h"
#include "common/parallel.h"
#include "estimation/estimator.h"
#include "estimation/light_uncertainty.h"
#include "estimation/truth_scorer.h"
#include "estimation/synth.h"
#include "scene/mesh.h"

namespace lp {
namespace {

double RelativeRmse(const ImageRGB& a, const View& v) {
  double se = 0, sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < v.valid.size(); ++i) {
    if (!v.valid[i]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = a.data[3 * i + c] - v.image.data[3 * i + c];
      se += d * d;
      sum += v.image.data[3 * i + c];
    }
    ++n;
  }
  return std::sqrt(se / (3.0 * n)) / (sum / (3.0 * n));
}

TEST(EstimateEndToEnd, OneLightDirectionAndRelighting) {
  // The bundled demo: 160x120, reference rendered at 256 samples per pixel, light 200 m away.
  const SceneBundle b = LoadSceneBundle(std::string(LIGHTPROBE_SOURCE_DIR) + "/assets/demo");
  EstimateOptions eo;
  eo.render_spp = 512;
  eo.scorer = TruthScorer::FromBundle(b);
  const EstimateResult r = Estimate(b, eo);
  ASSERT_FALSE(std::isnan(r.final_angular_error_deg));
  // Measured over seeds 1-5 at these settings: 0.85, 0.33, 1.10, 0.66, 0.89 degrees (this
  // test runs seed 1); a light one 21-ring cell off is 9 degrees away.
  EXPECT_LT(r.final_angular_error_deg, 2.5);
  // A light 200 m away is the map's, not a lamp's (the search found one and dropped it).
  EXPECT_TRUE(r.lighting.Count<PointLight>() == 0);
  // Re-render relative RMSE below 5 % (the target). Measured 4.7 %, of which ~3 %
  // is the floor of the comparison itself (Monte Carlo noise of both images, cell
  // discretization: the true light projected onto the cells re-renders at 3.3 %).
  EXPECT_LT(RelativeRmse(r.renders[0], b.views[0]), 0.05);
  EXPECT_FALSE(r.objective_increased);
  for (double v : r.lighting.map) ASSERT_TRUE(std::isfinite(v) && v >= 0);
  // Directions below the floor that no path reaches are left out.
  int left_out = 0;
  for (auto v : r.left_out) left_out += v;
  EXPECT_GT(left_out, 0);
  // The log has one row per solver iteration, time increasing.
  ASSERT_FALSE(r.convergence.empty());
  for (std::size_t i = 1; i < r.convergence.size(); ++i)
    EXPECT_GE(r.convergence[i].wall_seconds, r.convergence[i - 1].wall_seconds);
}

TEST(EstimateEndToEnd, ALampHalfAMetreAwayComesBackAsAPointLight) {
  // The synthetic near-light room: a sphere light of radius 5 cm 0.6 m from the centre,
  // rendered by this project's area-light tracer (not the point-light model).
  SynthOptions so;
  const SynthScene s = MakeSynth("near-light", so, "");
  ASSERT_EQ(s.lighting.lights.size(), 1u);
  const SphereLight& truth = s.lighting.lights[0];
  const Eigen::Vector3d intensity = truth.rgb_power / (4 * 3.14159265358979323846);  // a sphere's I = P / 4 pi
  EstimateOptions eo;
  eo.render = false;
  const EstimateResult r = Estimate(s.bundle, eo);
  ASSERT_EQ(r.lighting.Count<PointLight>(), 1u);
  // Its distance from the centre the scene places it around (0.6 m; 0.25 m from the mesh's
  // bounding-box centre, which the room's walls pull off the objects).
  const double distance = (truth.position - s.lighting.center).norm();
  const double error = (r.lighting.Of<PointLight>()[0].position - truth.position).norm();
  std::printf("lamp %.3f m off (%.1f %% of %.2f m); intensity %.4f vs %.4f\n", error, 100 * error / distance, distance,
              r.lighting.Of<PointLight>()[0].intensity.x(), intensity.x());
  // Targets: within 5 % of its distance (measured 2.4 %), intensity within 15 % (1.7 %).
  EXPECT_LT(error, 0.05 * distance);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.lighting.Of<PointLight>()[0].intensity[c], intensity[c], 0.15 * intensity[c]);
  EXPECT_FALSE(r.objective_increased);
  // How sure it is: a covariance per light, positive definite, the truth near its 95 %
  // region (inside at 7.81; measured 20.4 here: the window is wide; docs/benchmarks.md
  // measures the coverage, LampRecovery.TheTrueLampsLieInTheirRegionsAsOftenAsTheRegionsSay
  // checks it on ten lamps).
  ASSERT_EQ(r.uncertainty.size(), r.lighting.lights.size());
  const LightUncertainty& u = r.uncertainty.back();  // (directional lights first, then lamps)
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(u.shape_covariance).eigenvalues().minCoeff(), 0);
  EXPECT_GT(u.scale_sigma.minCoeff(), 0);
  EXPECT_TRUE(u.scale_sigma.allFinite());
  const double m = SquaredMahalanobis(truth.position - r.lighting.Of<PointLight>()[0].position, u.shape_covariance);
  std::printf("its 95 %% region: squared Mahalanobis distance of the truth %.2f\n", m);
  EXPECT_LT(m, 30);
  // The model selection's trial solves are in the log as "trial" rows (the lamp's held-out
  // fits with it, without it and far: three descents, each counting its iterations from
  // the start), in the rounds that chose, between the rounds' own rows.
  int trial_solves = 0;
  for (std::size_t i = 1; i < r.convergence.size(); ++i) {
    const ConvergenceRow &row = r.convergence[i], &before = r.convergence[i - 1];
    if (std::string(row.step) != "trial") continue;
    ASSERT_TRUE(std::isfinite(row.objective) && row.relative_rmse > 0);
    trial_solves += std::string(before.step) != "trial" || row.iteration <= before.iteration;
    EXPECT_EQ(row.round, before.round);
  }
  EXPECT_GE(trial_solves, 3);
}

TEST(EstimateEndToEnd, ADenseMeshIsTracedClusteredAndTheLampStaysFound) {
  // The near-light room's surfaces split into 40 times the triangles (as fine as a
  // reconstruction): with trace_pixels 4 the estimator traces them clustered on a grid of 4
  // pixels, and the lamp comes back within the same 5 % as from the room's own mesh.
  SynthOptions so;
  SynthScene s = MakeSynth("near-light", so, "");
  const SphereLight& truth = s.lighting.lights[0];
  EstimateOptions eo;
  eo.render = false;
  eo.trace_pixels = 4;
  eo.max_rounds = 1;
  const EstimateResult coarse = Estimate(s.bundle, eo);  // its own mesh is coarser than a pixel: traced as it is
  EXPECT_EQ(coarse.trace_cell_m, 0);
  EXPECT_EQ(coarse.traced_triangles, static_cast<int>(s.bundle.mesh.triangles.size()));

  s.bundle.mesh = RefineMesh(s.bundle.mesh, 40 * static_cast<int>(s.bundle.mesh.triangles.size()));
  eo.max_rounds = 4;
  const EstimateResult r = Estimate(s.bundle, eo);
  std::printf("traced %d of %d triangles (grid %.2f cm)\n", r.traced_triangles,
              static_cast<int>(s.bundle.mesh.triangles.size()), 100 * r.trace_cell_m);
  EXPECT_GT(r.trace_cell_m, 0);
  EXPECT_LT(4 * r.traced_triangles, static_cast<int>(s.bundle.mesh.triangles.size()));
  ASSERT_EQ(r.lighting.Count<PointLight>(), 1u);
  const double distance = (truth.position - s.lighting.center).norm();
  const double error = (r.lighting.Of<PointLight>()[0].position - truth.position).norm();
  std::printf("lamp %.3f m off (%.1f %% of %.2f m)\n", error, 100 * error / distance, distance);
  EXPECT_LT(error, 0.05 * distance);
}

// A live preview (LivePreview, what a growing scan gets): round 1 alone at half its
// samples, on the mesh clustered on a 3-pixel grid, no polish, no pictures; on the
// near-light room refined as fine as a reconstruction it still finds the lamp within 10 %
// of its distance (the full estimate: 5 %, above).
TEST(EstimateEndToEnd, ALivePreviewIsRoundOneAloneAndFindsTheLamp) {
  SynthScene s = MakeSynth("near-light", SynthOptions{}, "");
  const SphereLight& truth = s.lighting.lights[0];
  s.bundle.mesh = RefineMesh(s.bundle.mesh, 40 * static_cast<int>(s.bundle.mesh.triangles.size()));
  const EstimateOptions preview = LivePreview(EstimateOptions{});
  EXPECT_NO_THROW(Validate(preview));
  EXPECT_EQ(preview.tracer.spp, EstimateOptions{}.tracer.spp / 2);
  const EstimateResult r = Estimate(s.bundle, preview);
  EXPECT_EQ(r.rounds.size(), 1u);
  EXPECT_GT(r.trace_cell_m, 0) << "traced clustered";
  EXPECT_TRUE(r.renders.empty() && r.fits.empty()) << "no pictures";
  ASSERT_EQ(r.lighting.Count<PointLight>(), 1u);
  const double distance = (truth.position - s.lighting.center).norm();
  const double error = (r.lighting.Of<PointLight>()[0].position - truth.position).norm();
  std::printf("preview: lamp %.3f m off (%.1f %% of %.2f m) in %.2f s\n", error, 100 * error / distance, distance,
              r.total_seconds);
  EXPECT_LT(error, 0.10 * distance);
}

// Two lamps: LampRecovery.TwoLampsEachAtItsPlaceWithItsIntensity.

/// A synthetic scene of `w` x `h` pixels rendered at `spp`.
SceneBundle Synth(const char* name, int w, int h, int spp) {
  SynthOptions so;
  so.width = w;
  so.height = h;
  so.spp = spp;
  return MakeSynthScene(name, so, "");
}

TEST(EstimateEndToEnd, ImageScaledBy1000ScalesTheEstimate) {
  SceneBundle b = Synth("one-light", 48, 36, 64);
  EstimateOptions eo;
  eo.render = false;
  eo.max_rounds = 2;
  const EstimateResult r1 = Estimate(b, eo);
  for (float& v : b.views[0].image.data) v *= 1000.f;
  const EstimateResult r2 = Estimate(b, eo);
  double num = 0, den = 0;
  for (std::size_t i = 0; i < r1.lighting.map.size(); ++i) {
    num += std::pow(r2.lighting.map[i] - 1000 * r1.lighting.map[i], 2);
    den += std::pow(1000 * r1.lighting.map[i], 2);
  }
  // The lights beside the map scale too (a sun, when one is taken), and nothing else changes.
  ASSERT_EQ(r1.lighting.Count<DirectionalLight>(), r2.lighting.Count<DirectionalLight>());
  for (std::size_t k = 0; k < r1.lighting.Count<DirectionalLight>(); ++k) {
    num += (r2.lighting.Of<DirectionalLight>()[k].irradiance - 1000 * r1.lighting.Of<DirectionalLight>()[k].irradiance).squaredNorm();
    den += (1000 * r1.lighting.Of<DirectionalLight>()[k].irradiance).squaredNorm();
    EXPECT_LT(AngleDeg(r1.lighting.Of<DirectionalLight>()[k].direction, r2.lighting.Of<DirectionalLight>()[k].direction), 1e-6);
  }
  ASSERT_GT(den, 0);
  EXPECT_LT(std::sqrt(num / den), 1e-6);
}

TEST(EstimateEndToEnd, TheRelitViewIsTheFitWhereItUsedThePixelsAndARenderElsewhere) {
  // The fit's images (EstimateResult::fits, fit_view*.exr) are the fit itself (A lambda) on
  // the pixels the fit used, and traced on the others: their error there is the fit's, the pixels
  // left out are lit, and the image is the one a render traced anew (render_spp > 0, the
  // same estimate) gives, pixel for pixel within its noise (a pixel put in another's place
  // would not be).
  SceneBundle b = Synth("one-light", 40, 30, 64);
  View& v = b.views[0];
  const int w = v.camera.width;
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 12; ++x) v.valid[y * w + x] = 0;  // a corner the fit does not use
  EstimateOptions eo;
  eo.point_lights.max_lights = 0;
  eo.directional_lights = false;  // the map alone (a sun is sought whatever the lamps)
  eo.max_rounds = 2;
  eo.change_threshold = 0;
  const EstimateResult fit = Estimate(b, eo);
  ASSERT_EQ(fit.fits.size(), 1u);
  const ImageRGB& a = fit.fits[0];
  EXPECT_NEAR(RelativeRmse(a, v), fit.final_relative_rmse, 1e-5 * fit.final_relative_rmse);
  eo.render_spp = 1024;
  const EstimateResult traced = Estimate(b, eo);
  ASSERT_EQ(traced.lighting.map, fit.lighting.map);
  const ImageRGB& t = traced.renders[0];
  double corner_fit = 0, corner_traced = 0, d2 = 0, t2 = 0, shifted2 = 0;
  for (int y = 0; y < v.camera.height; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = 3 * static_cast<std::size_t>(y * w + x) + c;
        ASSERT_TRUE(std::isfinite(a.data[i]));
        if (y < 10 && x < 12) corner_fit += a.data[i], corner_traced += t.data[i];
        d2 += (a.data[i] - t.data[i]) * (a.data[i] - t.data[i]);
        t2 += t.data[i] * t.data[i];
        const std::size_t j = 3 * static_cast<std::size_t>(y * w + (x + 1) % w) + c;  // the pixel to the right
        shifted2 += (a.data[j] - t.data[i]) * (a.data[j] - t.data[i]);
      }
  const double apart = std::sqrt(d2 / t2), shifted = std::sqrt(shifted2 / t2);
  std::printf("corner: fit's render %.4f, traced %.4f; whole image %.4f apart (relative RMS), %.4f one pixel off\n",
              corner_fit, corner_traced, apart, shifted);
  EXPECT_GT(corner_traced, 0);
  EXPECT_NEAR(corner_fit, corner_traced, 0.05 * corner_traced);  // measured 0.9 %
  // Measured 0.082 (the fit's A averages 192 paths a pixel; the traced render 1024); the
  // fit's render moved by one pixel is the bound's other side.
  EXPECT_LT(apart, 0.12);
  EXPECT_GT(shifted, 0.12);
}

TEST(EstimateEndToEnd, TheLightsAreHandedOverOnceBeforeTheViewsAreRelit) {
  // EstimateOptions::on_lights (a caller writes lights.json there): once, with the lights
  // the result ends with, before any render exists, at a time no later than the estimate's.
  SceneBundle b = Synth("one-light", 40, 30, 64);
  EstimateOptions eo;
  eo.max_rounds = 2;
  eo.render_noise = 0.05;  // a clean render after the fit's: the pictures come after the lights
  int calls = 0;
  Lighting handed;
  std::size_t renders_then = 99, fits_then = 99;
  double seconds_then = -1;
  eo.on_lights = [&](const EstimateResult& r) {
    ++calls;
    handed = r.lighting;
    renders_then = r.renders.size();
    fits_then = r.fits.size();
    seconds_then = r.lights_seconds;
  };
  const EstimateResult r = Estimate(b, eo);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(renders_then, 0u);
  EXPECT_EQ(fits_then, 0u);
  ASSERT_EQ(r.renders.size(), 1u);
  ASSERT_FALSE(r.render_passes.empty());
  EXPECT_EQ(handed.map, r.lighting.map);
  EXPECT_EQ(handed.lights.size(), r.lighting.lights.size());
  EXPECT_EQ(seconds_then, r.lights_seconds);
  EXPECT_GT(r.lights_seconds, 0);
  EXPECT_LE(r.lights_seconds, r.total_seconds);
}

TEST(EstimateEndToEnd, TheFinalErrorIsTheFitsNotATrialsAfterIt) {
  // One round, which also chooses the map's prior: its last convergence rows are the
  // prior's trial fits on folds of the pixels (logged from parallel workers, in any
  // order). The final relative RMSE is the fit's own, the error of fit_view0 where the fit
  // used the pixels (all of them here), not a trial's.
  const SceneBundle b = Synth("one-light", 40, 30, 64);
  EstimateOptions eo;
  eo.max_rounds = 1;
  eo.render_noise = 0;
  eo.point_lights.max_lights = 0;
  eo.directional_lights = false;  // (the sky beside a sun is fitted after the rounds)
  const EstimateResult r = Estimate(b, eo);
  ASSERT_FALSE(r.convergence.empty());
  ASSERT_STREQ(r.convergence.back().step, "trial");
  ASSERT_EQ(r.fits.size(), 1u);
  EXPECT_NEAR(RelativeRmse(r.fits[0], b.views[0]), r.final_relative_rmse, 1e-5 * r.final_relative_rmse);
}

TEST(EstimateEndToEnd, RoundOnesFirstSolveIsHandedOverBeforeItsLampsAreSought) {
  // EstimateOptions::on_first_solve (a window shows it while round 1 seeks lamps): once,
  // before round 1 ends, with the map alone (no lamp yet, though the scene's lamp is found
  // later in round 1), lit, and a map as the round's own solve would have it.
  SceneBundle b = Synth("lamp-1m", 40, 30, 64);
  EstimateOptions eo;
  eo.max_rounds = 1;
  eo.render = false;
  std::vector<std::string> order;
  Lighting first;
  eo.on_first_solve = [&](const Lighting& l, const EnvMap& env) {
    order.push_back("first solve");
    first = l;
    EXPECT_EQ(l.map.size(), 3u * env.size());
  };
  eo.on_round = [&](const RoundInfo& info, const EnvMap&) { order.push_back("round " + std::to_string(info.round)); };
  const EstimateResult r = Estimate(b, eo);
  ASSERT_EQ(order, (std::vector<std::string>{"first solve", "round 1"}));
  EXPECT_TRUE(first.lights.empty());
  EXPECT_GE(r.lighting.Count<PointLight>(), 1u) << "round 1 found the lamp after the first solve";
  double power = 0;
  for (double v : first.map) power += v;
  EXPECT_GT(power, 0);
  // A warm start's first solve lacks the last estimate's lamps (they are the search's
  // candidates): not handed over, the last estimate stays shown.
  order.clear();
  eo.warm = WarmStartOf(r);
  Estimate(b, eo);
  EXPECT_EQ(order, (std::vector<std::string>{"round 1"}));
}

TEST(EstimateEndToEnd, SameSeedBitIdenticalForAnyThreadCount) {
  const SceneBundle b = Synth("two-light", 40, 30, 32);
  EstimateOptions eo;
  eo.tracer.spp = 16;
  eo.render_spp = 16;
  eo.max_rounds = 2;
  EstimateResult one, two;
  {
    ThreadLimit limit(1);
    one = Estimate(b, eo);
  }
  {
    ThreadLimit limit(2);
    two = Estimate(b, eo);
  }
  ASSERT_EQ(one.lighting.map.size(), two.lighting.map.size());
  for (std::size_t i = 0; i < one.lighting.map.size(); ++i) ASSERT_EQ(one.lighting.map[i], two.lighting.map[i]) << i;
  ASSERT_EQ(one.convergence.size(), two.convergence.size());
  // The same rows; the trial solves of the prior's folds, which run side by side, in the
  // order of their times: the same objectives, in some order.
  std::vector<double> trials_one, trials_two;
  for (std::size_t i = 0; i < one.convergence.size(); ++i) {
    ASSERT_STREQ(one.convergence[i].step, two.convergence[i].step) << i;
    if (std::string(one.convergence[i].step) != "trial") {
      ASSERT_EQ(one.convergence[i].objective, two.convergence[i].objective) << i;
      continue;
    }
    trials_one.push_back(one.convergence[i].objective);
    trials_two.push_back(two.convergence[i].objective);
  }
  std::sort(trials_one.begin(), trials_one.end());
  std::sort(trials_two.begin(), trials_two.end());
  EXPECT_FALSE(trials_one.empty());
  EXPECT_EQ(trials_one, trials_two);
  ASSERT_EQ(one.renders.size(), 1u);
  ASSERT_EQ(one.renders[0].data, two.renders[0].data);
  // A different seed gives a different answer (the comparison above can fail).
  eo.tracer.seed = 2;
  const EstimateResult other = Estimate(b, eo);
  EXPECT_NE(other.lighting.map, one.lighting.map);
}

}  // namespace
}  // namespace lp

namespace lp {
namespace {

/// `warm`'s map moved onto an EnvMap of the same rings about `up` (each new cell takes the
/// old cell its direction falls in): the same light, laid out on another up.
WarmStart OnUp(const EstimateResult& r, const Eigen::Vector3d& up) {
  WarmStart w;
  w.lighting = r.lighting;
  w.rings = r.env.rings();
  w.up = up;
  const EnvMap moved(w.rings, up);
  w.lighting.map.assign(3 * moved.size(), 0.0);
  for (int j = 0; j < moved.size(); ++j)
    for (int c = 0; c < 3; ++c) w.lighting.map[3 * j + c] = r.lighting.map[3 * r.env.Lookup(moved.direction(j)) + c];
  return w;
}

// A live estimate starts from the last one (EstimateOptions::warm): round 1's first solve
// starts at its map, in this estimate's units (image units over its image mean) and resampled
// onto this estimate's cells when the up moved (a new snapshot's up comes from its own mesh).
// Its first row is then near the cold estimate's end; the cold start's first row is far from it.
TEST(EstimateEndToEnd, AWarmStartBeginsAtTheLastEstimateWhereverItsUpPoints) {
  const SceneBundle b = LoadSceneBundle(std::string(LIGHTPROBE_SOURCE_DIR) + "/assets/demo");
  EstimateOptions eo;
  eo.render = false;
  const EstimateResult cold = Estimate(b, eo);
  const Eigen::Vector3d tilted = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()) * b.up;
  for (const Eigen::Vector3d& up : {b.up, tilted}) {
    // The images 3x as bright: the map given in the last estimate's image units is put in this one's.
    SceneBundle brighter = b;
    for (View& v : brighter.views)
      for (float& x : v.image.data) x *= 3;
    WarmStart w = OnUp(cold, up);
    for (double& x : w.lighting.map) x *= 3;
    eo.warm = std::make_shared<const WarmStart>(w);
    const EstimateResult warm = Estimate(brighter, eo);
    const double first_cold = cold.convergence.front().relative_rmse,
                 first_warm = warm.convergence.front().relative_rmse, end = cold.final_relative_rmse;
    std::printf("up tilted %.0f deg: first row %.4f warm, %.4f cold; the cold estimate ends at %.4f, the warm at %.4f\n",
                std::acos(std::clamp(up.dot(b.up), -1.0, 1.0)) * 180 / M_PI, first_warm, first_cold, end,
                warm.final_relative_rmse);
    EXPECT_GT(first_cold, 3 * end);
    EXPECT_LT(first_warm, 1.5 * end);
    EXPECT_LT(warm.final_relative_rmse, 1.1 * end);
  }
}

}  // namespace
}  // namespace lp
