#include "estimation/estimate_options.h"

#include <cmath>
#include <cstdlib>

#include "common/error.h"

namespace lp {
namespace {

using Type = EstimateOption::Type;
constexpr double kInf = std::numeric_limits<double>::infinity();

#define LP_GET(expr) [](const EstimateOptions& o) -> double { return static_cast<double>(o.expr); }
#define LP_SET(expr, T) [](EstimateOptions* o, double v) { o->expr = static_cast<T>(v); }

/// The final renders' options (EstimateOptions::render_spp, render_noise, render_seconds).
std::vector<EstimateOption> RenderOptions() {
  return {
      {"render-spp", "render_spp",
       "samples per pixel of the final relit render (render_view*), every pixel traced again; 0 = a clean render "
       "(--render-noise)",
       Type::kInt, 0, kInf, false, LP_GET(render_spp), LP_SET(render_spp, int), "", 0, 0, {}},
      {"render-noise", "render_noise",
       "the clean render (render_view*) is traced in passes until its relative noise (its two halves' difference) is "
       "at most this; 0 = write the fit as the render",
       Type::kReal, 0, 1, false, LP_GET(render_noise), LP_SET(render_noise, double), "", 0, 0, {}},
      {"render-seconds", "render_seconds",
       "the clean render's passes stop before this many seconds; 0 = as long as the estimate took (at least 2)",
       Type::kReal, 0, kInf, false, LP_GET(render_seconds), LP_SET(render_seconds, double), "", 0, 0, {}},
      {"render-denoise", "render_denoise",
       "the clean render's noise smoothed out over the pixels that see the same surface (its albedo kept sharp, the "
       "lights' direct light traced over each pixel); the passes stop at the denoised render's noise",
       Type::kBool, 0, 1, false, LP_GET(render_denoise), LP_SET(render_denoise, bool), "", 0, 0, {}},
  };
}

/// The options of the lights beside the map (MakeTable's).
std::vector<EstimateOption> LightOptions() {
  return {
      {"point-lights", "point_lights",
       "point lights (lamps in the room) at most, beside the environment map; 0 = the map alone", Type::kInt, 0, 16,
       false, LP_GET(point_lights.max_lights), LP_SET(point_lights.max_lights, int), "point lights", 0, 8, {}},
      {"point-spp", "point_spp", "paths per pixel the point lights' columns and positions use", Type::kInt, 1, 1024,
       false, LP_GET(point_lights.spp), LP_SET(point_lights.spp, int), "", 0, 0, {}},
      {"debias-columns", "debias_columns",
       "1 = the lights' fit takes their columns' Monte Carlo noise out of its objective (alone it stops a lamp's "
       "drift out along its ray; in the estimate not better so far: docs/method.md); 0 = the plain objective",
       Type::kBool, 0, 1, false, LP_GET(point_lights.debiased), LP_SET(point_lights.debiased, bool), "", 0, 0, {}},
      {"clipped-rows", "clipped_rows",
       "1 (the default) = the pixels the camera clipped on the mesh are fitted as lower bounds (the render must "
       "reach them), the pixels next to any clipped pixel as upper bounds (bloom only brightens); 0 = clipped pixels "
       "dropped, a glowing "
       "surface's radiance bounded below by them",
       Type::kBool, 0, 1, false, LP_GET(clipped_rows), LP_SET(clipped_rows, bool), "", 0, 0, {}},
      {"seen-lamps", "seen_lamps",
       "1 = the search for lamps also tries the places where the cameras saw clipped blobs (by the mesh's depth, or "
       "triangulated across views where the bulb returned no depth); 0 = the grid around the scene alone",
       Type::kBool, 0, 1, false, LP_GET(point_lights.seen), LP_SET(point_lights.seen, bool), "", 0, 0, {}},
      {"hold-seen", "hold_seen",
       "1 = the lamp round 1 kept nearest a triangulated seen place, if near it, is held there (its place measured; "
       "its intensity and radius fitted); 0 = refined like any lamp",
       Type::kBool, 0, 1, false, LP_GET(point_lights.hold_seen), LP_SET(point_lights.hold_seen, bool), "", 0, 0, {}},
      {"polish-spp", "polish_spp",
       "after the last round the lamps are refined again on fresh paths, this many per pixel on a share of the rows "
       "(the fit debiased); 0 = not; -1 = 64 on a scan (an albedo pass de-lit the colours seen) and where the paths' "
       "noise limits a lamp's place more than the images do, else not",
       Type::kInt, -1, 1024, false, LP_GET(point_lights.polish_spp), LP_SET(point_lights.polish_spp, int), "", 0, 0,
       {}},
      {"directional-lights", "directional_lights",
       "try a directional light (a sun: sharp shadows) where the map concentrates its power; 0 = never",
       Type::kBool, 0, 1, false, LP_GET(directional_lights), LP_SET(directional_lights, bool),
       "directional light (a sun)", 0, 1, {}},
      {"emitters", "emitters",
       "look for glowing surfaces (lamp shades, frosted windows, screens) where the views see pixels brighter than "
       "a white surface under the lights; 0 = never",
       Type::kBool, 0, 1, false, LP_GET(emitters), LP_SET(emitters, bool), "", 0, 0, {}},
  };
}

std::vector<EstimateOption> MakeTable() {
  std::vector<EstimateOption> table = {
      {"rings", "rings", "rings of the environment map (21 -> 522 directions)", Type::kInt, kMinRings, kMaxRings, false,
       LP_GET(rings), LP_SET(rings, int), "rings", 5, 41, {}},
      {"spp", "spp",
       "the map's path samples per pixel per round (after round 1 fewer, down to a quarter, where the map renders "
       "under half the light)",
       Type::kInt, 1, kInf, false, LP_GET(tracer.spp), LP_SET(tracer.spp, int), "samples/pixel", 8, 256, {}},
      {"bounces", "bounces", "surface interactions per path (1 = direct only)", Type::kInt, 1, kInf, false,
       LP_GET(tracer.bounces), LP_SET(tracer.bounces, int), "bounces", 1, 8, {}},
      {"solver", "solver", "fast (majorize-minimize NNQP) or gradient (paper's projected GD)", Type::kChoice, 0, 1,
       false, LP_GET(solver), LP_SET(solver, SolverKind), "solver", 0, 0, {"fast", "gradient"}},
      {"alpha", "alpha", "activation penalty weight, per 19200 observed pixels (scaled with the pixel count)",
       Type::kReal, 0, kInf, false, LP_GET(objective.alpha), LP_SET(objective.alpha, double), "alpha", 0, 0, {}},
      {"smooth", "smooth",
       "weight of the map's smoothness between neighbouring cells, relative to a cell's median curvature in the data (0: none)",
       Type::kReal, 0, kInf, false, LP_GET(objective.smooth), LP_SET(objective.smooth, double), "smooth", 0, 0, {}},
      {"beta", "beta", "activation penalty sharpness (0: no penalty)", Type::kReal, 0, kInf, false,
       LP_GET(objective.beta),
       LP_SET(objective.beta, double), "beta", 0, 0, {}},
      {"sigma", "sigma", "Cauchy scale, relative to the mean pixel value", Type::kReal, 0, kInf, true,
       LP_GET(objective.sigma), LP_SET(objective.sigma, double), "sigma", 0, 0, {}},
      {"nee-floor", "nee_floor",
       "share of next-event samples spread over all reachable cells (the rest follow the estimate)", Type::kReal, 0, 1,
       false, LP_GET(tracer.nee_floor), LP_SET(tracer.nee_floor, double), "", 0, 0, {}},
      {"max-rounds", "max_rounds", "sequential Monte Carlo rounds at most", Type::kInt, 1, kInf, false,
       LP_GET(max_rounds), LP_SET(max_rounds, int), "rounds", 1, 6, {}, "rounds"},
      {"change", "change_threshold",
       "stop when the rendered estimate changes by less than this share between rounds (beside a window's opening the map too; 0: run every round)",
       Type::kReal, 0, kInf, false, LP_GET(change_threshold), LP_SET(change_threshold, double), "", 0, 0, {}},
      {"albedo-passes", "albedo_passes",
       "albedo refinements of a reconstructed mesh at most (de-lit by the estimate, segmented again, rounds go on; a "
       "pass after the first only while the lights still move: --albedo-settle; 0 = keep the bundle's albedo)",
       Type::kInt, 0, kMaxAlbedoPasses, false, LP_GET(albedo_passes), LP_SET(albedo_passes, int), "albedo passes", 0,
       kMaxAlbedoPasses, {}},
      {"albedo-settle", "albedo_settle",
       "a further albedo pass only while the last moved a lamp by more than this share of its distance from the "
       "scene's centre (a directional light: radians; 0 = every pass)",
       Type::kReal, 0, 1, false, LP_GET(albedo_settle), LP_SET(albedo_settle, double), "", 0, 0, {}},
      {"room-albedo", "room_albedo",
       "a reconstructed mesh's albedo is scaled so its median over the surface (in a room, a wall) is this; 0 = "
       "the colours' scale",
       Type::kReal, 0, 0.95 /* kMaxAlbedo as a decimal */, false, LP_GET(room_albedo), LP_SET(room_albedo, double),
       "", 0, 0, {}},
      {"free-albedo", "free_albedo",
       "after an albedo pass, fit the lights' places with each segment's albedo left free (the shading within "
       "the segments places them); 0 = under the de-lit albedo",
       Type::kBool, 0, 1, false, LP_GET(free_albedo), LP_SET(free_albedo, bool), "", 0, 0, {}},
      {"choose-prior", "choose_prior",
       "choose the map's prior by the pixels the fit did not use: the activation penalty from --alpha down to "
       "--alpha/30, the strongest within one standard error of the best held-out loss; 0 = --alpha as given",
       Type::kBool, 0, 1, false, LP_GET(choose_prior), LP_SET(choose_prior, bool), "", 0, 0, {}},
      {"albedo-samples", "albedo_samples", "paths per vertex for the irradiance an albedo pass de-lights by",
       Type::kInt, 1, 4096, false, LP_GET(albedo_samples), LP_SET(albedo_samples, int), "", 0, 0, {}},
      {"albedo-noise", "albedo_noise",
       "an albedo pass traces more paths (up to --albedo-samples a cluster) only where the irradiance's relative "
       "standard error is above this; 0 = --albedo-samples everywhere",
       Type::kReal, 0, 1, false, LP_GET(albedo_noise), LP_SET(albedo_noise, double), "", 0, 0, {}},
      {"pre-albedo-stride", "pre_albedo_stride",
       "the rounds before the first albedo pass fit the pixels on a grid of this many (at most round 1's); 1 = "
       "every pixel",
       Type::kInt, 1, 16, false, LP_GET(pre_albedo_stride), LP_SET(pre_albedo_stride, int), "", 0, 0, {}},
      {"trace-pixels", "trace_pixels",
       "trace the mesh clustered on a grid of this many pixels (what one spans on the nearest tenth of the surfaces "
       "seen) where it is finer; 0 = trace the bundle's mesh as it is",
       Type::kReal, 0, kMaxTracePixels, false, LP_GET(trace_pixels), LP_SET(trace_pixels, double),
       "traced mesh (pixels)", 0, 4, {}},
  };
  for (EstimateOption& o : LightOptions()) table.push_back(std::move(o));
  table.push_back({"seed", "seed", "random seed (same seed => same result for any thread count)", Type::kInt, 0,
                   9007199254740992.0, false, LP_GET(tracer.seed), LP_SET(tracer.seed, std::uint64_t), "", 0, 0, {}});
  for (EstimateOption& o : RenderOptions()) table.push_back(std::move(o));
  return table;
}

#undef LP_GET
#undef LP_SET

/// A number as it would be typed (no trailing zeros).
std::string Number(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

bool PositiveFinite(const EstimateOption& option) {
  return option.min_exclusive && option.min == 0 && std::isinf(option.max);
}

bool InRange(const EstimateOption& option, double v) {
  return v >= option.min && v <= option.max && !(option.min_exclusive && v == option.min) &&
         !(PositiveFinite(option) && !std::isfinite(v));
}

/// "between 2 and 181", "at least 1", "positive and finite".
std::string RangeText(const EstimateOption& option) {
  if (PositiveFinite(option)) return "positive and finite";
  if (std::isinf(option.max)) return "at least " + Number(option.min);
  return "between " + Number(option.min) + " and " + Number(option.max);
}

}  // namespace

const std::vector<EstimateOption>& EstimateOptionTable() {
  static const std::vector<EstimateOption> table = MakeTable();
  return table;
}

const EstimateOption* FindEstimateOption(const std::string& key) {
  for (const EstimateOption& o : EstimateOptionTable())
    if (key == o.key || (*o.alias && key == o.alias)) return &o;
  return nullptr;
}

void SetEstimateOption(EstimateOptions* o, const std::string& key, const std::string& text) {
  const EstimateOption* option = FindEstimateOption(key);
  if (!option) throw InputError("unknown setting '" + key + "'");
  if (option->type == Type::kChoice) {
    for (std::size_t i = 0; i < option->names.size(); ++i)
      if (text == option->names[i]) return option->set(o, static_cast<double>(i));
    std::string names;
    for (const std::string& n : option->names) names += (names.empty() ? "" : " or ") + n;
    throw InputError("unknown " + key + " '" + text + "' (use " + names + ")");
  }
  if (option->type == Type::kBool && (text == "true" || text == "false")) return option->set(o, text == "true");
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0') throw InputError(key + " must be a number, not '" + text + "'");
  // Out of range is refused here too: an int cannot hold every double.
  if (!InRange(*option, v)) throw InputError(key + " must be " + RangeText(*option) + ", not " + text);
  if (option->type != Type::kReal && v != std::floor(v))
    throw InputError(key + " must be a whole number, not '" + text + "'");
  option->set(o, v);
}

std::string EstimateOptionText(const EstimateOption& option, const EstimateOptions& o) {
  const double v = option.get(o);
  if (option.type == Type::kChoice) return option.names.at(static_cast<std::size_t>(v));
  return Number(v);
}

void Validate(const EstimateOptions& o) {
  for (const EstimateOption& option : EstimateOptionTable())
    if (!InRange(option, option.get(o))) throw InputError(std::string(option.key) + " must be " + RangeText(option));
}

EstimateOptions LivePreview(EstimateOptions full) {
  full.max_rounds = 1;
  full.tracer.spp = std::max(1, full.tracer.spp / 2);
  full.albedo_passes = 0;
  full.point_lights.polish_spp = 0;
  full.trace_pixels = kPreviewTracePixels;
  full.render = false;
  full.render_noise = 0;
  return full;
}

}  // namespace lp
