// `lightprobe estimate`: light-source estimation on a scene bundle.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>

#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "common/atomic_file.h"
#include "common/color.h"
#include "common/image_io.h"
#include "common/parallel.h"
#include "common/plot.h"
#include "common/timer.h"
#include "estimation/envmap.h"
#include "estimation/error_display.h"
#include "estimation/lights_file.h"
#include "estimation/truth_scorer.h"

namespace lp::app {
namespace fs = std::filesystem;
using nlohmann::json;

std::string DefaultDataDir() {
  if (const char* env = std::getenv("LIGHTPROBE_DATA")) return env;
#ifdef LIGHTPROBE_SOURCE_DIR
  return (fs::path(LIGHTPROBE_SOURCE_DIR) / "assets").lexically_normal().string();
#else
  return "assets";
#endif
}

void AddEstimateOptions(CLI::App& cmd, EstimateOptions* o, int* threads) {
  // Every option of the table (estimation/estimate_options.h): read as text and set (and
  // its range checked) by SetEstimateOption, so the command line, the viewer's command file
  // and its Settings accept the same values.
  for (const EstimateOption& option : EstimateOptionTable()) {
    const std::string key = option.key;
    cmd.add_option_function<std::string>(
           "--" + key, [o, key](const std::string& text) { SetEstimateOption(o, key, text); }, option.help)
        ->default_str(EstimateOptionText(option, *o))
        ->type_name(option.type == EstimateOption::Type::kChoice ? "NAME"
                    : option.type == EstimateOption::Type::kReal ? "FLOAT"
                    : option.type == EstimateOption::Type::kBool ? "0/1"
                                                                 : "INT");
  }
  cmd.add_option("--threads", *threads, "worker threads (0 = all cores)")->capture_default_str();
}

std::string Num(double v) { return CsvNumber(v); }

/// convergence.png: error against wall-clock time, one series per sMC round (the rows of
/// convergence.csv): relative RMSE, objective and, with truth.json, the dominant light's
/// angular error.
static void WriteConvergencePlot(const fs::path& path, const std::vector<ConvergenceRow>& rows) {
  if (rows.empty()) return;
  PlotPanel rmse{"photometric error", "wall-clock seconds", "relative RMSE", false, true, {}, {}};
  PlotPanel objective{"objective", "wall-clock seconds", "E(lambda)", false, true, {}, {}};
  PlotPanel angle{"dominant light direction error", "wall-clock seconds", "degrees", false, false, {}, {}};
  PlotPanel position{"point light position error", "wall-clock seconds", "metres (worst light)", false, false, {}, {}};
  bool any_angle = false, any_position = false;
  for (const ConvergenceRow& row : rows) {
    // Round 1's graduated steps (a sigma below kGraduatedSigmaStart) measure the objective
    // at other scales: each its own series.
    std::string label = "round " + std::to_string(row.round);
    if (row.sigma != rows.back().sigma) label += ", sigma " + Num(row.sigma);
    if (row.albedo_pass > 0) label += ", albedo pass " + std::to_string(row.albedo_pass);
    if (std::string(row.step) != "solve") label += ", " + std::string(row.step);
    // The model selection's trial solves, each its own descent of its own problem: small
    // dots, not joined, one colour in every round.
    const bool trial = std::string(row.step) == "trial";
    if (trial) label = "trial solves (choosing lights and prior)";
    for (PlotPanel* p : {&rmse, &objective, &angle, &position})
      if (p->series.empty() || p->series.back().label != label)
        p->series.push_back({label, {}, {}, !trial, true, trial ? 1 : 3});
    rmse.series.back().x.push_back(row.wall_seconds);
    rmse.series.back().y.push_back(row.relative_rmse);
    objective.series.back().x.push_back(row.wall_seconds);
    objective.series.back().y.push_back(row.objective);
    angle.series.back().x.push_back(row.wall_seconds);
    angle.series.back().y.push_back(row.angular_error_deg);
    any_angle = any_angle || std::isfinite(row.angular_error_deg);
    position.series.back().x.push_back(row.wall_seconds);
    position.series.back().y.push_back(row.position_error_m);
    any_position = any_position || std::isfinite(row.position_error_m);
  }
  std::vector<PlotPanel> panels{rmse, objective};
  if (any_angle) panels.push_back(angle);
  if (any_position) panels.push_back(position);
  WritePlotPng(path, "lightprobe estimate: error against run time", panels, static_cast<int>(panels.size()));
}

/// clean_render.png: the clean render's relative noise against its seconds (log-log), each
/// pass a point, the noise asked a dashed line; none when there was no clean render.
static void WriteCleanRenderPlot(const fs::path& out, const EstimateOptions& o, const EstimateResult& r) {
  if (r.render_passes.empty()) return;
  PlotSeries noise{"relative noise", {}, {}};
  for (const RenderPass& p : r.render_passes) noise.x.push_back(p.seconds), noise.y.push_back(p.noise);
  PlotPanel panel;
  panel.title = "render_view*, pass by pass";
  panel.x_label = "seconds";
  panel.y_label = "relative noise";
  panel.series.push_back(noise);
  panel.reference_y.push_back(o.render_noise);
  WritePlotPng(out / "clean_render.png", "the clean render's noise", {panel}, 1);
}

/// envmap.exr, envmap.png (scaled to the brightest cell) and envmap_directions.csv.
static void WriteEnvMap(const fs::path& out, const EstimateResult& r) {
  const EnvMap& env = r.env;
  const std::vector<double>& lambda = r.lighting.map;
  WriteExr(out / "envmap.exr", env.ToEquirect(lambda, 128));
  double peak = 0;
  for (double v : lambda) peak = std::max(peak, v);
  WritePngSrgb(out / "envmap.png", env.ToEquirect(lambda, 128), peak > 0 ? static_cast<float>(1 / peak) : 1.f);
  std::ostringstream dirs;
  dirs << "x,y,z,solid_angle,r,g,b,left_out\n";
  for (int j = 0; j < env.size(); ++j) {
    const auto& d = env.direction(j);
    dirs << Num(d.x()) << ',' << Num(d.y()) << ',' << Num(d.z()) << ',' << Num(env.solid_angle(j)) << ','
         << Num(lambda[3 * j]) << ',' << Num(lambda[3 * j + 1]) << ',' << Num(lambda[3 * j + 2]) << ','
         << int(r.left_out[j]) << '\n';
  }
  WriteTextAtomically(out / "envmap_directions.csv", dirs.str());
}

static std::string Fmt(const char* fmt, double a, double b, double c, double d, double e) {
  char buf[1024];
  std::snprintf(buf, sizeof buf, fmt, a, b, c, d, e);
  return buf;
}

/// lights.json: the map (when it lights anything), the point lights, the directional ones
/// and the emitters (their triangles first, in emitters.ply: a reader of lights.json finds them).
static void WriteLights(const fs::path& out, const EstimateResult& r) {
  LightsFile lights{"", r.lighting.lights, r.uncertainty, r.openings};
  for (double v : r.lighting.map)
    if (v > 0) lights.environment = "envmap.exr";
  WriteEmittersPly(out / "emitters.ply", r.lighting.lights);
  WriteOpeningsPly(out / "openings.ply", r.openings);
  WriteTextAtomically(out / "lights.json", LightsJson(lights));
}

/// report.json's "model": which lighting model was chosen and why.
static json ModelJson(const EstimateOptions& o, const EstimateResult& r) {
  std::string chosen = "environment map";
  if (const std::size_t n = r.lighting.Count<PointLight>()) chosen += " + " + std::to_string(n) + " point light(s)";
  if (const std::size_t n = r.lighting.Count<DirectionalLight>())
    chosen += " + " + std::to_string(n) + " directional light(s)";
  json seen = json::array();
  for (const SeenLamp& l : r.seen_lamps)
    seen.push_back({{"position", {l.position.x(), l.position.y(), l.position.z()}},
                    {"how", l.how},
                    {"views", l.views},
                    {"pixels", l.pixels},
                    {"gap", l.gap},
                    {"held", std::any_of(r.lighting.lights.begin(), r.lighting.lights.end(), [&](const Light& k) {
                       const PointLight* p = std::get_if<PointLight>(&k);
                       return p && p->held && (p->position - l.position).norm() < 1e-9;
                     })}});
  return {{"chosen", chosen},
          {"max_point_lights", o.point_lights.max_lights},
          {"choices", r.point_light_choices},
          {"seen_lamps", seen},
          {"rule", Fmt("round 1 looks for lamps with the map dark: greedily the candidate position around the "
                       "scene that best explains what the lights so far leave, all of them refined together "
                       "(Levenberg-Marquardt on positions and intensities), while each lowers the loss by %g %%; "
                       "then the map and the lights are solved together, and each light is kept only if the map "
                       "and the other lights, fitted without a held-out %g %% of the pixels, predict those pixels "
                       "worse without it (by %g %%) and it renders at least %g %% of the light seen; lights refined beyond %g scene radii are far lights, left "
                       "to the map",
                       100 * o.point_lights.min_gain, 100 * o.point_lights.holdout, 100 * o.point_lights.min_gain,
                       100 * o.point_lights.min_share, o.point_lights.far)}};
}

/// convergence.csv and convergence.png.
static void WriteConvergence(const fs::path& out, const EstimateResult& r) {
  std::ostringstream conv;
  conv << "wall_seconds,round,iteration,objective,photometric_rmse,relative_rmse,angular_error_deg,sigma,step,"
          "point_lights,position_error_m,albedo_pass\n";
  for (const auto& row : r.convergence)
    conv << Num(row.wall_seconds) << ',' << row.round << ',' << row.iteration << ',' << Num(row.objective) << ','
         << Num(row.photometric_rmse) << ',' << Num(row.relative_rmse) << ',' << Num(row.angular_error_deg) << ','
         << Num(row.sigma) << ',' << row.step << ',' << row.point_lights << ',' << Num(row.position_error_m) << ','
         << row.albedo_pass << '\n';
  WriteTextAtomically(out / "convergence.csv", conv.str());
  WriteConvergencePlot(out / "convergence.png", r.convergence);
}

/// render_view<k>.exr/.png (the clean render), fit_view<k>.exr (the fit) and
/// error_view<k>.png of view k; returns its entry of report.json.
static json WriteView(const fs::path& out, std::size_t k, const View& v, const ImageRGB& img, const ImageRGB& fit) {
  const std::string name = "render_view" + std::to_string(k), fit_name = "fit_view" + std::to_string(k) + ".exr";
  WriteExr(out / (name + ".exr"), img);
  WriteExr(out / fit_name, fit);
  // Same exposure for render and error image: the observed image's white level.
  const float white = WhiteLevel(v);
  WritePngSrgb(out / (name + ".png"), img, 1 / white);
  // The picture of the error from the clean render; the number from the fit (what the
  // estimate minimized; the clean render's samples depend on the time it was given).
  WriteHeatmapPng(out / ("error_view" + std::to_string(k) + ".png"), img.width, img.height, ErrorImage(img, v),
                  kErrorDisplayFraction * white);
  double se = 0;
  for (float e : ErrorImage(fit, v))
    if (e >= 0) se += 3.0 * e * e;
  const int n = static_cast<int>(std::count(v.valid.begin(), v.valid.end(), 1));
  double mean_obs = 0;
  for (std::size_t i = 0; i < v.valid.size(); ++i)
    if (v.valid[i]) mean_obs += (v.image.data[3 * i] + v.image.data[3 * i + 1] + v.image.data[3 * i + 2]) / 3.0;
  mean_obs = n > 0 ? mean_obs / n : 0.0;
  const double render_rmse = n > 0 ? std::sqrt(se / (3.0 * n)) : 0.0;
  return {{"render", name + ".exr"},
          {"fit", fit_name},
          {"error_image", "error_view" + std::to_string(k) + ".png"},
          {"valid_pixels", n},
          {"masked_out", v.masked_out},
          {"non_finite", v.non_finite},
          {"negative", v.negative},
          {"saturated", v.saturated},
          {"render_rmse", render_rmse},
          {"render_relative_rmse", mean_obs > 0 ? render_rmse / mean_obs : 0.0}};
}

/// report.json's "settings": the options the estimate ran with (every option of the table,
/// a choice by its name), and what follows from them.
static json SettingsJson(const EstimateOptions& o, const EstimateResult& r) {
  const char* tunables = std::getenv("GLIBC_TUNABLES");  // (main.cpp's UseHugePages)
  json settings = {{"directions", r.env.size()}, {"alpha_effective", r.objective_params.alpha},
                   {"threads", HardwareThreads()}, {"min_throughput", o.tracer.min_throughput},
                   {"combine_rounds", o.combine_rounds},
                   {"huge_pages", tunables != nullptr && std::strstr(tunables, "glibc.malloc.hugetlb=1") != nullptr}};
  for (const EstimateOption& option : EstimateOptionTable()) {
    if (option.type == EstimateOption::Type::kChoice) settings[option.report] = EstimateOptionText(option, o);
    else if (option.type == EstimateOption::Type::kReal) settings[option.report] = option.get(o);
    else if (option.type == EstimateOption::Type::kBool) settings[option.report] = option.get(o) != 0;
    else settings[option.report] = static_cast<std::int64_t>(option.get(o));
  }
  return settings;
}

/// report.json's "seconds": where the time went.
static json SecondsJson(const EstimateResult& r, double command_seconds) {
  json seconds = {{"total", command_seconds}, {"bvh", r.bvh_seconds}, {"trace", r.trace.seconds},
                  {"render", r.render_seconds}, {"clean_render", r.clean_render_seconds},
                  {"estimate", r.total_seconds}, {"lights", r.lights_seconds}};
  double solve = 0;
  for (const auto& ri : r.rounds) solve += ri.solve_seconds;
  seconds["solve"] = solve;
  seconds["albedo"] = r.albedo_seconds;
  seconds["prior"] = r.prior.seconds;
  return seconds;
}

/// report.json's "prior": the map's prior the data chose, each weight tried with its
/// held-out loss, and why.
static json PriorJson(const EstimateOptions& o, const EstimateResult& r) {
  const PriorChoice& p = r.prior;
  json tried = json::array();
  for (const PriorChoice::Tried& t : p.tried)
    tried.push_back({{"alpha", t.alpha},
                     {"smooth", t.smooth},
                     {"lights", t.lights},
                     {"heldout_loss", t.loss},
                     {"standard_error", t.standard_error},
                     {"chosen", p.IsChosen(t)}});
  return {{"alpha", std::isfinite(p.chosen) ? p.chosen : o.objective.alpha},
          {"smooth", std::isfinite(p.chosen) ? p.chosen_smooth : o.objective.smooth},
          {"chosen", std::isfinite(p.chosen)},
          {"lights_dropped", p.lights_dropped},
          {"why", p.why},
          {"tried", tried},
          {"folds", p.folds},
          {"blocks", p.blocks},
          {"rule", "the map and the lights' intensities (the lights held where they are), and the map alone, fitted "
                   "without a fold of the views' blocks (4 x 4 a view; block (x, y) of view v in fold (x + y + v) "
                   "mod 4) and scored by the Cauchy loss on its pixels, at each alpha from the given one down (with "
                   "a directional light, the lights at the given one only); of each, the strongest alpha whose loss "
                   "exceeds the least by no more than one standard error of that difference (over the blocks); the "
                   "lights stay if theirs is below the map alone's by the model selection's min_gain, and the "
                   "estimate is solved again at the alpha chosen"}};
}

/// Albedo refinement: done for a reconstructed mesh (it carries the colours seen), left out
/// where the albedo is known (no shaded colours) or when turned off. Writes albedo_mesh.ply
/// when done; returns report.json's "albedo".
/// albedo_mesh.ply: the bundle's mesh with the albedo the lights go with (when the estimate
/// changed it: refined or scaled).
static void WriteAlbedoMesh(const fs::path& out, const SceneBundle& bundle, const EstimateResult& r) {
  if (r.albedo.empty()) return;
  Mesh mesh = bundle.mesh;
  mesh.albedo = r.albedo;
  mesh.shaded.clear();
  WritePly(out / "albedo_mesh.ply", mesh);
}

/// report.json's "albedo" (its mesh: WriteAlbedoMesh's).
static json AlbedoJson(const EstimateResult& r) {
  json albedo = {{"refined", r.albedo_passes > 0},
                 {"passes", r.albedo_passes},
                 {"segments", r.albedo_segments},
                 {"paths", r.albedo_paths},
                 {"scale", r.albedo_scale}};
  if (std::isfinite(r.albedo_last_move)) albedo["last_move"] = r.albedo_last_move;
  if (r.albedo_scale != 1)
    albedo["scale_rule"] = "the bundle's albedo (the colours seen, flattened) scaled so its median luminance over "
                           "the vertices is --room-albedo; every albedo pass keeps that median; the lights are in "
                           "its terms";
  if (!r.albedo.empty()) albedo["mesh"] = "albedo_mesh.ply";
  if (r.albedo_passes == 0) {
    // The reason as the command line says it (the library names no flags).
    albedo["why_not"] = r.albedo_left_out == AlbedoLeftOut::kNoPasses ? "--albedo-passes 0"
                                                                     : ToString(r.albedo_left_out);
  }
  return albedo;
}

/// report.json's "left_out": what the estimate did not use.
static json LeftOutJson(const SceneBundle& bundle, const EstimateResult& r) {
  int left_out = 0;
  for (auto v : r.left_out) left_out += v;
  return {{"directions_unreached", left_out},
          {"pixels_not_traced", r.trace.pixels_skipped},
          {"paths_stopped_roulette", r.trace.stopped_roulette},
          {"paths_stopped_negligible", r.trace.stopped_negligible},
          {"paths_stopped_max_bounces", r.trace.stopped_max_bounces},
          {"degenerate_triangles_removed", bundle.degenerate_triangles_removed}};
}

/// The lights of `lighting` of kind T as lights.json holds them (with `uncertainty`, one
/// per light of `lighting`, when given).
template <class T>
static json LightsOfKind(const Lighting& lighting, const std::vector<LightUncertainty>& uncertainty = {}) {
  return json::parse(LightsJson({"", lighting.lights, uncertainty, {}}))[LightsKey(T{})];
}

static json RoundsJson(const EstimateResult& r) {
  json rounds = json::array();
  for (const auto& ri : r.rounds)
    rounds.push_back({{"round", ri.round}, {"pixels", ri.pixels}, {"spp", ri.spp}, {"trace_seconds", ri.trace_seconds}, {"solve_seconds", ri.solve_seconds},
                      {"solver_iterations", ri.solver_iterations}, {"objective", ri.objective},
                      {"change", ri.change}, {"image_change", ri.image_change}, {"kkt_violation", ri.kkt_violation},
                      {"nonzeros", ri.nonzeros}, {"unknown_cells", ri.unknown_cells},
                      {"point_lights", LightsOfKind<PointLight>(ri.lighting)},
                      {"light_iterations", ri.light_iterations}});
  return rounds;
}

/// report.json's "final": the estimate's fit and dominant directions.
static json FinalJson(const EstimateResult& r) {
  json dominant = json::array();
  for (const auto& d : r.dominant) dominant.push_back({d.x(), d.y(), d.z()});
  json result = {{"photometric_rmse", r.final_rmse}, {"relative_rmse", r.final_relative_rmse},
                 {"kkt_violation", r.kkt_violation}, {"objective_increased", r.objective_increased},
                 {"dominant_directions", dominant}};
  if (!std::isnan(r.final_angular_error_deg)) result["angular_error_deg"] = r.final_angular_error_deg;
  if (!std::isnan(r.final_position_error_m))
    result["position_error_m"] = std::isfinite(r.final_position_error_m) ? json(r.final_position_error_m) : json("inf");
  if (std::isfinite(r.final_position_error_share)) result["position_error_share"] = r.final_position_error_share;
  result["rendered_fraction"] = r.rendered_fraction;
  ForEachKind([&](auto kind) {
    result[LightsKey(kind)] = LightsOfKind<decltype(kind)>(r.lighting, r.uncertainty);
  });
  result["scene_centre"] = {r.scene_centre.x(), r.scene_centre.y(), r.scene_centre.z()};
  return result;
}

static json EnvMapFrameJson(const EnvMap& env) {
  return {{"up", {env.up().x(), env.up().y(), env.up().z()}},
          {"frame_x", {env.frame_x().x(), env.frame_x().y(), env.frame_x().z()}},
          {"frame_y", {env.frame_y().x(), env.frame_y().y(), env.frame_y().z()}}};
}

/// out_dir, created where it is not.
static fs::path OutputDirectory(const std::string& out_dir) {
  const fs::path out(out_dir);
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) throw InputError(out_dir, "cannot create output directory: " + ec.message());
  return out;
}

void WriteEstimateLights(const std::string& out_dir, const SceneBundle& bundle, const EstimateResult& r) {
  const fs::path out = OutputDirectory(out_dir);
  WriteEnvMap(out, r);
  WriteAlbedoMesh(out, bundle, r);
  WriteLights(out, r);
}

void WriteEstimateOutputs(const std::string& out_dir, const SceneBundle& bundle, const EstimateOptions& o,
                          const EstimateResult& r, double command_seconds, bool lights_written) {
  const fs::path out = OutputDirectory(out_dir);
  if (!lights_written) WriteEstimateLights(out_dir, bundle, r);
  WriteConvergence(out, r);
  json views = json::array();
  for (std::size_t k = 0; k < r.renders.size(); ++k)
    views.push_back(WriteView(out, k, bundle.views[k], r.renders[k], r.fits[k]));
  json rep;
  rep["scene"] = fs::absolute(bundle.dir).lexically_normal().string();
  rep["settings"] = SettingsJson(o, r);
  rep["seconds"] = SecondsJson(r, command_seconds);
  rep["albedo"] = AlbedoJson(r);
  WriteCleanRenderPlot(out, o, r);
  rep["clean_render"] = json::array();  // its passes: error (noise) against run time
  for (const RenderPass& p : r.render_passes)
    rep["clean_render"].push_back({{"spp", p.spp}, {"seconds", p.seconds}, {"relative_noise", p.noise}});
  rep["left_out"] = LeftOutJson(bundle, r);
  rep["trace"] = {{"paths", r.trace.paths},
                  {"rays", r.trace.rays},
                  {"mesh", {{"triangles", r.traced_triangles},
                            {"vertices", r.traced_vertices},
                            {"grid_m", r.trace_cell_m},
                            {"cluster_seconds", r.cluster_seconds}}}};
  rep["rounds"] = RoundsJson(r);
  rep["clipped"] = {{"rows", r.clipped_rows}, {"bloom_upper_bounds", r.bloom_rows}};
  rep["views"] = views;
  rep["image_mean"] = r.image_mean;
  rep["final"] = FinalJson(r);
  rep["model"] = ModelJson(o, r);
  rep["prior"] = PriorJson(o, r);
  rep["warnings"] = r.warnings;
  rep["envmap_convention"] =
      "equirectangular, width = 2*height; row y: polar angle (y+0.5)/H*pi from up (top = up); column x: azimuth "
      "(x+0.5)/W*2pi from frame_x towards frame_y = up x frame_x";
  rep["envmap_frame"] = EnvMapFrameJson(r.env);
  WriteTextAtomically(out / "report.json", rep.dump(2) + "\n");
}

namespace {

/// `--warm DIR`: an earlier estimate's lighting (lights.json, its envmap.exr, and from
/// report.json the map's rings and up) as the start of this one.
std::shared_ptr<const WarmStart> ReadWarmStart(const fs::path& dir) {
  const fs::path lights_path = dir / "lights.json", report_path = dir / "report.json";
  const LightsFile file = ReadLightsFile(lights_path);
  auto warm = std::make_shared<WarmStart>();
  warm->lighting.lights = file.lights;
  try {
    const json report = json::parse(ReadTextFile(report_path));
    warm->rings = report.at("settings").at("rings").get<int>();
    const auto up = report.at("envmap_frame").at("up").get<std::vector<double>>();
    if (up.size() != 3) throw InputError(report_path.string(), "envmap_frame.up is not 3 numbers");
    warm->up = Eigen::Vector3d(up[0], up[1], up[2]);
  } catch (const json::exception& e) {
    throw InputError(report_path.string(), std::string("cannot read the map's rings and up: ") + e.what());
  }
  if (!(warm->rings >= kMinRings && warm->rings <= kMaxRings) || !(warm->up.norm() > 0.5))
    throw InputError(report_path.string(), "the map's rings or up are out of range");
  if (!file.environment.empty())
    warm->lighting.map = EnvMap(warm->rings, warm->up.normalized()).FromEquirect(ReadEquirectMap(dir / file.environment));
  return warm;
}

}  // namespace

Run AddEstimate(CLI::App& app) {
  auto* cmd = app.add_subcommand("estimate", "estimate the environment lighting of a scene bundle");
  auto scene = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto o = std::make_shared<EstimateOptions>();
  auto threads = std::make_shared<int>(0);
  auto quiet = std::make_shared<bool>(false);
  cmd->add_option("SCENE_DIR", *scene, "scene bundle directory (scene.json, mesh.ply, views)")->required();
  cmd->add_option("--out", *out, "output directory")->required();
  AddEstimateOptions(*cmd, o.get(), threads.get());
  cmd->add_flag("--quiet", *quiet, "no progress lines");
  auto warm = std::make_shared<std::string>();
  cmd->add_option("--warm", *warm,
                  "start from an earlier estimate's output directory (its map as the first round's, its lamps as the "
                  "search's first candidates), as a live estimate does");
  return [=] {
    Stopwatch sw;
    ThreadLimit limit(*threads);
    Validate(*o);
    if (!*quiet) o->progress = [](const std::string& s) { std::fprintf(stderr, "  %s\n", s.c_str()); };
    if (!*quiet) std::fprintf(stderr, "loading %s\n", scene->c_str());
    SceneBundle bundle = LoadSceneBundle(*scene);
    if (!*quiet) {
      for (std::size_t k = 0; k < bundle.views.size(); ++k) {
        const View& v = bundle.views[k];
        std::fprintf(stderr, "  view %zu: %dx%d, %d pixels masked out, %d non-finite, %d negative, %d saturated\n",
                     k, v.camera.width, v.camera.height, v.masked_out, v.non_finite, v.negative, v.saturated);
      }
      std::fprintf(stderr, "  mesh: %zu vertices, %zu triangles (%d degenerate removed)\n",
                   bundle.mesh.positions.size(), bundle.mesh.triangles.size(), bundle.degenerate_triangles_removed);
    }
    if (!warm->empty()) o->warm = ReadWarmStart(*warm);
    o->time_offset = sw.Seconds();
    o->scorer = TruthScorer::FromBundle(bundle, o->point_lights.far);  // truth.json's errors, when it has one
    // lights.json as soon as the lights are final, before the pictures (the clean render).
    EstimateOptions eo = *o;
    bool lights_written = false;
    eo.on_lights = [&](const EstimateResult& lit) {
      WriteEstimateLights(*out, bundle, lit);
      lights_written = true;
      if (!*quiet) std::fprintf(stderr, "  lights.json written after %.2f s (the pictures follow)\n", sw.Seconds());
    };
    EstimateResult r = Estimate(bundle, eo);
    WriteEstimateOutputs(*out, bundle, eo, r, sw.Seconds(), lights_written);
    std::printf("estimated %d directions (%d rings) in %.2f s; relative RMSE %.4f", r.env.size(), o->rings,
                sw.Seconds(), r.final_relative_rmse);
    if (!std::isnan(r.final_angular_error_deg)) std::printf("; dominant light error %.2f deg", r.final_angular_error_deg);
    std::printf("; %zu point light(s)", r.lighting.Count<PointLight>());
    if (std::isfinite(r.final_position_error_m))
      std::printf("; the lamp is %.1f cm from the true one (%.1f %% of its distance from the scene)",
                  100 * r.final_position_error_m, 100 * r.final_position_error_share);
    std::printf("\nresults in %s (lights.json, envmap.exr, envmap_directions.csv, render_view*.png, fit_view*.exr, "
                "clean_render.png, error_view*.png, convergence.csv/.png, report.json%s)\n",
                fs::absolute(*out).lexically_normal().c_str(), r.albedo.empty() ? "" : ", albedo_mesh.ply");
    std::fflush(stdout);
    for (const std::string& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  };
}

}  // namespace lp::app
