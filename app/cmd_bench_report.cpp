// `lightprobe bench-report`: error against run time for every method and for the knobs
// of the fast one, on the synthetic scenes with known lighting. Writes report.md with
// PNG plots and the CSV behind each plot.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include "app/commands.h"
#include "common/atomic_file.h"
#include "common/parallel.h"
#include "common/plot.h"
#include "common/timer.h"
#include "estimation/path_tracer.h"
#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "scene/ray_tracer.h"
#include "estimation/synth.h"
#include "estimation/truth_scorer.h"
#include "estimation/truth.h"

namespace lp::app {
namespace fs = std::filesystem;

namespace {

const char* kFast = "fast";
const char* kPgd = "paper PGD";
const char* kFd = "FD Jacobian (extrapolated)";
const char* kMapAlone = "fast, map alone";

struct ReportOptions {
  std::string out = "out/report";
  std::vector<std::string> sizes = {"160x120", "320x240"};
  std::vector<std::string> scenes = {"one-light", "two-light", "near-light", "sun-and-sky", "env-studio",
                                     "env-sunset", "frag115",   "lamp-0.5m",  "lamp-1m",     "lamp-2m",
                                     "lamp-4m",   "two-lamps", "lamp-and-sky"};
  std::string data;
  double gradient_cap = 15;  ///< seconds per sMC round for the paper's PGD
  int eval_spp = 64;         ///< samples per pixel of the held-out relit renders
  int synth_spp = 256;
  bool sweep_all_sizes = false;
  bool quick = false;
  int threads = 0;
};

/// Errors of one estimate (after one round, or at the end of a run).
struct Point {
  std::string setting;
  int round = 0;
  double seconds = 0;
  double fitted = NAN, relit = NAN, angle = NAN, envmap = NAN;
  double position = NAN;  ///< the worst near true light's distance to the nearest point light (m)
};

struct IterPoint {
  int round = 0, iteration = 0;
  double seconds = 0, fitted = NAN, angle = NAN, position = NAN;
};

struct Curve {
  std::string name;
  std::vector<IterPoint> iterations;  ///< per solver iteration (methods only)
  std::vector<Point> points;          ///< per sMC round (methods) or per setting (knob sweeps)
};

struct Case {
  std::string scene, size;
  SynthScene synth;
  SceneBundle fit;  ///< the fitted view only
  View held_out;
  std::unique_ptr<RayTracer> tracer;
  std::vector<TruthLight> truth;
  bool near_truth = false;  ///< a true light is near (the scene is one for point lights)
  /// The true lighting integrated over the cells, per ring count (empty: not far / no map).
  std::map<int, std::vector<double>> true_cells;
  double relit_floor = NAN;   ///< relit error of the true lighting projected on the default cells
  double render_seconds = 0;  ///< one render of the fitted view at the default settings (FD's unit)
  std::vector<Curve> curves;  ///< fast first
  PriorChoice prior;          ///< the map's prior fast's run chose (each weight's held-out loss)
  bool swept = false;         ///< the knobs were swept (the sMC-rounds knob is fast's rounds)
};

std::string Fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

/// Relit error on the held-out view under `lighting` (image units), rendered with the run's
/// own tracer settings at eval_spp, the map importance-sampled by the estimate itself.
double RelitError(const Case& c, const EnvMap& env, const Lighting& lighting, const TracerOptions& run,
                  int eval_spp) {
  TracerOptions t = run;
  t.spp = eval_spp;
  t.seed = 4242;
  const CellSampler sampler(env, lighting.map, {}, run.nee_floor);
  const auto img = RenderLighting(*c.tracer, env, lighting, sampler, {c.held_out}, t, false);
  return RelativeImageRmse(img[0], c.held_out.image, c.held_out.valid);
}

/// The worst near true light's position error (NaN when the scene has none), near as the
/// estimator's default says (within 5 scene radii of the mesh's centre).
double PositionError(const Case& c, const std::vector<PointLight>& points) {
  if (!c.near_truth) return NAN;
  return WorstPositionError(points, c.truth, c.tracer->center(), PointLightOptions{}.far * c.tracer->radius());
}

Point Evaluate(const Case& c, const EnvMap& env, const Lighting& lighting, const std::vector<std::uint8_t>& left_out,
               const TracerOptions& run, int eval_spp) {
  Point p;
  const std::vector<double>& lambda = lighting.map;
  const std::vector<PointLight> points = lighting.Of<PointLight>();
  p.relit = RelitError(c, env, lighting, run, eval_spp);
  if (!c.truth.empty()) p.angle = DominantAngularErrorDeg(env, lambda, points, c.tracer->center(), c.truth);
  p.position = PositionError(c, points);
  const bool has_map = c.synth.lighting.equirect.pixels() > 0 || static_cast<bool>(c.synth.lighting.sky);
  if (has_map && c.synth.lighting.far)
    p.envmap = EnvMapRelativeError(env, lambda, c.true_cells.at(env.rings()), left_out);
  return p;
}

/// Runs one estimate on the fitted view; returns the result (no relit render inside).
EstimateResult RunEstimate(const Case& c, EstimateOptions eo) {
  eo.render = false;
  eo.progress = nullptr;
  eo.scorer = TruthScorer::FromBundle(c.fit, eo.point_lights.far);
  return Estimate(c.fit, eo);
}

/// The per-round curve of a run (relit, angle, envmap evaluated after each round).
Curve MethodCurve(const Case& c, const std::string& name, const EstimateResult& r, const EstimateOptions& eo,
                  int eval_spp) {
  Curve cv;
  cv.name = name;
  for (const ConvergenceRow& row : r.convergence)
    cv.iterations.push_back(
        {row.round, row.iteration, row.wall_seconds, row.relative_rmse, row.angular_error_deg, row.position_error_m});
  for (const RoundInfo& ri : r.rounds) {
    Point p = Evaluate(c, r.env, ri.lighting, r.left_out, eo.tracer, eval_spp);
    p.round = ri.round;
    p.seconds = ri.end_seconds;
    p.setting = "round " + std::to_string(ri.round);
    for (const ConvergenceRow& row : r.convergence)
      if (row.round == ri.round) p.fitted = row.relative_rmse;
    cv.points.push_back(p);
  }
  return cv;
}

/// The finite-difference baseline: the same estimate with each round's trace of A replaced
/// by (unknown cells + 1) renders of the fitted view (its A is the same; only time differs).
Curve FdCurve(const Curve& fast, const EstimateResult& r, double render_seconds) {
  Curve fd;
  fd.name = kFd;
  std::vector<double> offset;
  double sum = 0;
  for (const RoundInfo& ri : r.rounds) {
    sum += (ri.unknown_cells + 1) * render_seconds - ri.trace_seconds;
    offset.push_back(sum);
  }
  for (IterPoint p : fast.iterations) {
    p.seconds += offset[p.round - 1];
    fd.iterations.push_back(p);
  }
  for (Point p : fast.points) {
    p.seconds += offset[p.round - 1];
    fd.points.push_back(p);
  }
  return fd;
}

/// Where the default stopping rule (image change < threshold) would have stopped a run
/// that was forced through every round.
std::size_t DefaultStopRound(const EstimateResult& r, double threshold) {
  for (std::size_t k = 1; k < r.rounds.size(); ++k)
    if (r.rounds[k].image_change < threshold) return k;
  return r.rounds.size() - 1;
}

double TimeToReach(const std::vector<std::pair<double, double>>& series, double target) {
  for (const auto& [s, v] : series)
    if (std::isfinite(v) && v <= target) return s;
  return NAN;
}

std::string MachineLine() {
  std::ifstream in("/proc/cpuinfo");
  std::string line, model = "unknown CPU";
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      model = line.substr(line.find(':') + 2);
      break;
    }
  return model + ", " + std::to_string(HardwareThreads()) + " hardware threads";
}

/// The knob settings swept (the default setting's point is taken from the forced fast run).
struct Knobs {
  std::vector<int> spps = {4, 16, 64, 256}, rings = {9, 15, 31}, bounces = {1, 2, 4};
};

using Cases = std::vector<std::unique_ptr<Case>>;

/// The synthetic render settings of one image size "WxH" (one fitted view, one held out).
SynthOptions ReferenceOptions(const std::string& size, int spp) {
  SynthOptions so;
  if (std::sscanf(size.c_str(), "%dx%d", &so.width, &so.height) != 2) throw InputError("--sizes: bad size " + size);
  so.spp = spp;
  so.held_out_views = 1;
  return so;
}

// ---- the plots and their CSVs ----

struct Metric {
  const char* key;
  const char* title;
  const char* y_label;
  double Point::*field;
  bool per_iteration;  // methods plotted per solver iteration (fitted RMSE, angle)
};

const Metric kMetrics[] = {
    {"fitted_rmse", "(a) photometric RMSE on the fitted view", "relative RMSE", &Point::fitted, true},
    {"relit_error", "(b) relighting error on the held-out view", "relative RMSE", &Point::relit, false},
    {"light_angle", "(c) dominant light direction error", "degrees", &Point::angle, true},
    {"envmap_error", "(d) environment map error vs the true map per cell", "relative L2", &Point::envmap, false},
    {"position_error", "(e) lamp position error (worst near light)", "metres", &Point::position, true},
};

/// One curve of case c as a series of metric m (per solver iteration or per point); its
/// values are appended to the plot's CSV.
PlotSeries MetricSeries(const Metric& m, const Case& c, const std::string& name, const Curve& cv, bool per_iteration,
                        std::ostream& csv) {
  PlotSeries s;
  s.label = name;
  if (per_iteration) {
    s.markers = false;
    for (const IterPoint& it : cv.iterations) {
      const double v = m.field == &Point::fitted ? it.fitted : m.field == &Point::angle ? it.angle : it.position;
      s.x.push_back(it.seconds);
      s.y.push_back(v);
      csv << c.scene << ',' << c.size << ",\"" << name << "\",," << it.round << ',' << it.iteration << ','
          << Num(it.seconds) << ',' << Num(v) << '\n';
    }
  } else {
    for (const Point& pt : cv.points) {
      s.x.push_back(pt.seconds);
      s.y.push_back(pt.*(m.field));
      csv << c.scene << ',' << c.size << ",\"" << name << "\"," << pt.setting << ',' << pt.round << ",,"
          << Num(pt.seconds) << ',' << Num(pt.*(m.field)) << '\n';
    }
  }
  return s;
}

/// Case c's panel of metric m (its values appended to the plot's CSV); none where it has no
/// finite value.
std::optional<PlotPanel> MetricPanel(const Metric& m, const Case& c, std::ostream& csv) {
  PlotPanel p;
  p.title = c.scene;
  p.x_label = "wall-clock seconds";
  p.y_label = m.y_label;
  if (m.field == &Point::relit && std::isfinite(c.relit_floor)) p.reference_y.push_back(c.relit_floor);
  for (const Curve& cv : c.curves)
    p.series.push_back(MetricSeries(m, c, cv.name, cv, m.per_iteration && !cv.iterations.empty(), csv));
  // The sMC-rounds knob is the fast run after each round: a series of its own where
  // the fast run is drawn per iteration (per round it is the fast curve itself).
  if (m.per_iteration && c.swept)
    p.series.push_back(MetricSeries(m, c, "fast: sMC rounds", c.curves.front(), false, csv));
  for (const PlotSeries& s : p.series)
    for (double v : s.y)
      if (std::isfinite(v)) return p;
  return std::nullopt;
}

/// The plot of metric m at one size (PNG + CSV, none without a panel); returns its part of
/// report.md.
std::string WritePlot(const fs::path& out, const Metric& m, const std::string& size, const Cases& cases) {
  std::vector<PlotPanel> panels;
  std::ostringstream csv;
  csv << "scene,size,curve,setting,round,iteration,seconds,value\n";
  for (const auto& c : cases)
    if (c->size == size)
      if (std::optional<PlotPanel> p = MetricPanel(m, *c, csv)) panels.push_back(std::move(*p));
  if (panels.empty()) return "";
  const std::string stem = std::string(m.key) + "_" + size;
  WritePlotPng(out / (stem + ".png"), std::string(m.title) + ", " + size, panels, 3);
  WriteTextAtomically(out / (stem + ".csv"), csv.str());
  std::ostringstream figure;
  figure << "### " << m.title << ", " << size << "\n\n![" << m.title << "](" << stem << ".png)\n\nData: [" << stem
         << ".csv](" << stem << ".csv)\n\n";
  return figure.str();
}

/// The map's prior at one size: per scene, the held-out loss of each weight the default
/// estimate tried, with the lights it found and with the map alone (one standard error of
/// its difference from the least either side), and the one it chose; the smooth maps' in a
/// panel of their own (PNG + CSV; none where no scene chose); returns its part of report.md.
std::string WritePriorPlot(const fs::path& out, const std::string& size, const Cases& cases) {
  std::vector<PlotPanel> panels;
  std::ostringstream csv;
  csv << "scene,size,alpha,smooth,lights,heldout_loss,standard_error,chosen\n";
  for (const auto& c : cases) {
    const PriorChoice& p = c->prior;
    if (c->size != size || p.tried.empty()) continue;
    // Two panels a scene: the activation penalty's weights, then the smoothness's (at the
    // weakest of those weights).
    for (const bool smooth : {false, true}) {
      PlotPanel panel;
      panel.title = c->scene + (smooth ? ": smooth maps" : "");
      panel.x_label = smooth ? "the smoothness's weight" : "alpha (the map's prior)";
      panel.y_label = "held-out loss";
      panel.log_y = false;
      PlotSeries with{"with the lights", {}, {}}, alone{"the map alone", {}, {}}, chosen{"chosen", {}, {}, false, true};
      PlotSeries band{"+/- 1 SE", {}, {}, false, true};
      for (const PriorChoice::Tried& t : p.tried) {
        if ((t.smooth > 0) != smooth) continue;
        const double x = smooth ? t.smooth : t.alpha;
        PlotSeries& s = t.lights > 0 ? with : alone;
        s.x.push_back(x);
        s.y.push_back(t.loss);
        for (double d : {-t.standard_error, t.standard_error}) band.x.push_back(x), band.y.push_back(t.loss + d);
        if (p.IsChosen(t)) chosen.x.push_back(x), chosen.y.push_back(t.loss);
        csv << c->scene << ',' << size << ',' << t.alpha << ',' << t.smooth << ',' << t.lights << ',' << t.loss << ','
            << t.standard_error << ',' << p.IsChosen(t) << '\n';
      }
      for (PlotSeries* s : {&band, &with, &alone, &chosen})  // (the chosen marker drawn last, on top)
        if (!s->x.empty()) panel.series.push_back(*s);
      if (!panel.series.empty()) panels.push_back(std::move(panel));
    }
  }
  if (panels.empty()) return "";
  const std::string stem = "prior_" + size;
  WritePlotPng(out / (stem + ".png"), "the map's prior: held-out loss of each weight tried, " + size, panels, 3);
  WriteTextAtomically(out / (stem + ".csv"), csv.str());
  return "### The map's prior, " + size + "\n\n![the map's prior](" + stem + ".png)\n\nData: [" + stem + ".csv](" +
         stem + ".csv)\n\n";
}

/// Every metric's plot at every size, and the map's prior's; returns their part of report.md.
std::string WritePlots(const fs::path& out, const std::vector<std::string>& sizes, const Cases& cases) {
  std::string figures;
  for (const Metric& m : kMetrics)
    for (const std::string& size : sizes) figures += WritePlot(out, m, size, cases);
  for (const std::string& size : sizes) figures += WritePriorPlot(out, size, cases);
  return figures;
}

// ---- the summary table: time to reach a stated error ----

std::string TimeCell(double s) { return std::isfinite(s) ? Fmt("%.2f", s) : std::string("not reached"); }

std::string Ratio(double a, double b) {
  return std::isfinite(a) && std::isfinite(b) && b > 0 ? Fmt("%.1fx", a / b) : std::string("-");
}

/// (seconds, fitted RMSE) per solver iteration.
std::vector<std::pair<double, double>> FittedSeries(const Curve& cv) {
  std::vector<std::pair<double, double>> s;
  for (const IterPoint& p : cv.iterations) s.emplace_back(p.seconds, p.fitted);
  return s;
}

/// (seconds, relit error) per point.
std::vector<std::pair<double, double>> RelitSeries(const Curve& cv) {
  std::vector<std::pair<double, double>> s;
  for (const Point& p : cv.points) s.emplace_back(p.seconds, p.relit);
  return s;
}

const Curve& FindCurve(const Case& c, const char* name) {
  const Curve* found = nullptr;
  for (const Curve& cv : c.curves)
    if (cv.name == name) found = &cv;
  return *found;
}

/// One row: the time fast, PGD and FD took to reach the fitted and the relit targets.
std::string SummaryRow(const Case& c) {
  const Curve &f = FindCurve(c, kFast), &g = FindCurve(c, kPgd), &d = FindCurve(c, kFd);
  const double fit_target = 1.01 * std::max(f.iterations.back().fitted, g.iterations.back().fitted);
  double relit_target = 0;
  for (const Curve* cv : {&f, &g}) {
    double best = 1e300;
    for (const Point& p : cv->points) best = std::min(best, p.relit);
    relit_target = std::max(relit_target, best);
  }
  relit_target *= 1.05;
  const double tf = TimeToReach(FittedSeries(f), fit_target), tg = TimeToReach(FittedSeries(g), fit_target),
               td = TimeToReach(FittedSeries(d), fit_target);
  const double rf = TimeToReach(RelitSeries(f), relit_target), rg = TimeToReach(RelitSeries(g), relit_target),
               rd = TimeToReach(RelitSeries(d), relit_target);
  std::ostringstream row;
  row << "| " << c.scene << " | " << c.size << " | " << Fmt("%.4f", fit_target) << " | " << TimeCell(tf) << " | "
      << TimeCell(tg) << " | " << TimeCell(td) << " | " << Ratio(tg, tf) << " | " << Ratio(td, tf) << " | "
      << Fmt("%.4f", relit_target) << " | " << TimeCell(rf) << " | " << TimeCell(rg) << " | " << TimeCell(rd)
      << " |\n";
  return row.str();
}

std::string SummaryTable(const Cases& cases) {
  std::ostringstream table;
  table << "| scene | size | target fitted RMSE | fast (s) | paper PGD (s) | FD (s) | PGD / fast | FD / fast | "
           "target relit error | fast (s) | paper PGD (s) | FD (s) |\n"
        << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& c : cases) table << SummaryRow(*c);
  return table.str();
}

// ---- report.md ----

/// report.md: what was run and measured, the summary table and the plots. `total` times
/// the whole run; `fd_check` is the FD extrapolation's check (empty: not run).
std::string ReportMarkdown(const ReportOptions& o, const Stopwatch& total, const std::string& fd_check,
                           const std::string& table, const std::string& figures) {
  std::ostringstream md;
  const std::time_t now = std::time(nullptr);
  char date[64];
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  md << "# Error against run time\n\n"
     << "Generated by `lightprobe bench-report --out " << o.out << "` on " << date << ", " << MachineLine()
     << "; the whole run took " << Fmt("%.0f", total.Seconds()) << " s.\n"
     << "Sizes: ";
  for (const auto& s : o.sizes) md << s << ' ';
  md << "; knob sweeps at " << (o.sweep_all_sizes ? std::string("every size") : o.sizes.front())
     << (o.quick ? " (quick smoke run: reduced settings)" : "") << ".\n\n"
     << "## What is measured\n\n"
     << "Every scene is synthetic with known lighting (`lightprobe synth --list`), rendered at " << o.synth_spp
     << " spp with two views: the estimate fits the first, the second is held out.\n\n"
     << "- **fast**: the default estimator (majorize-minimize solver), forced through every sMC round so the "
        "rounds curve is complete. **paper PGD**: the same estimator with the paper's projected gradient descent, "
     << Fmt("capped at %.0f s per round. ", o.gradient_cap)
     << "**FD Jacobian (extrapolated)**: the same estimate with each round's trace of A replaced by one render "
        "per unknown cell plus one; with common random numbers and frozen importance its A is the traced A "
        "(transport_test checks A lambda = render), so its errors are fast's and its time is fast's plus "
        "(cells + 1) x the measured time of one render minus the trace. "
     << (fd_check.empty() ? std::string() : fd_check) << "\n"
     << "- **fast: spp / rings / bounces**: one full default estimate per setting (default stopping rule); "
        "the default setting's point is the fast run where that rule would have stopped. **fast: sMC rounds**: "
        "the fast run after each round.\n"
     << "- (a) relative RMSE of the fit on the fitted view (per solver iteration for the methods); (b) relative "
        "RMSE of the held-out view re-rendered under the estimate (" << o.eval_spp
     << " spp, evaluation time not counted; the dashed line is the same measure for the true lighting "
        "integrated over the default 21-ring cells and rendered the same way: what the cell model does with the "
        "exact answer, not a lower bound, since one cell moves a small light to the cell's centre); (c) mean "
        "angle between "
        "the strongest (up to 2) true lights and the estimate's dominant directions; (d) solid-angle weighted "
        "relative L2 error of the estimated map against the true lighting integrated over each cell, over the "
        "cells some path reached (far scenes lit by a sky or an HDR map); (e) on the scenes with a lamp "
        "(a true light within 5 scene radii): the worst distance from a true lamp to the nearest estimated "
        "point light, per solver iteration (infinite, so not drawn, while there is none). There **fast, map "
        "alone** (`--point-lights 0`, the far-light model) runs beside the default.\n"
     << "- Times are wall-clock seconds from the start of the estimate (BVH, traces, solves), one process, "
        "all cores. Machines here are noisy: compare ratios within one run.\n\n"
     << "## Time to reach a stated error\n\n"
     << "Fitted target: 1.01 x the worse of fast's and PGD's final fitted RMSE. Relit target: 1.05 x the worse "
        "of their best relit errors (relit is measured once per round).\n\n"
     << table << "\n## Plots\n\n" << figures;
  return md.str();
}

// ---- the run ----

/// One bench-report run: a case per size and scene (methods, knob sweeps), then the plots,
/// the summary table and report.md.
class ReportRun {
 public:
  explicit ReportRun(const ReportOptions& o) : o_(o), out_(o.out) {
    if (o.quick) knobs_.spps = {4}, knobs_.rings = {9}, knobs_.bounces = {1};
  }

  void Run() {
    std::error_code ec;
    fs::create_directories(out_, ec);
    if (ec) throw InputError(o_.out, "cannot create report directory: " + ec.message());
    for (std::size_t si = 0; si < o_.sizes.size(); ++si) {
      const SynthOptions so = ReferenceOptions(o_.sizes[si], o_.synth_spp);
      for (const std::string& scene : o_.scenes) AddCase(scene, o_.sizes[si], so, si == 0 || o_.sweep_all_sizes);
    }
    const std::string figures = WritePlots(out_, o_.sizes, cases_);
    const std::string table = SummaryTable(cases_);
    WriteTextAtomically(out_ / "report.md", ReportMarkdown(o_, total_, fd_check_, table, figures));
    std::printf("report in %s (report.md, %s) after %.0f s\n",
                fs::absolute(out_ / "report.md").lexically_normal().c_str(), "PNG + CSV per plot", total_.Seconds());
  }

 private:
  /// One progress line, after the seconds since the start.
  void Progress(const std::string& text) const {
    std::printf("[%6.0f s] %s\n", total_.Seconds(), text.c_str());
    std::fflush(stdout);
  }

  void AddCase(const std::string& scene, const std::string& size, const SynthOptions& so, bool sweep) {
    std::unique_ptr<Case> c = MakeCase(scene, size, so);
    const EstimateResult fast = RunMethods(c.get());
    if (sweep) SweepKnobs(c.get(), fast);
    // The FD extrapolation checked once against a real FD Jacobian at 9 rings.
    if (fd_check_.empty() && !o_.quick) fd_check_ = CheckFdExtrapolation(*c);
    cases_.push_back(std::move(c));
  }

  /// The reference views rendered, the true lighting on the cells of every ring count swept,
  /// its relit error and FD's unit of work.
  std::unique_ptr<Case> MakeCase(const std::string& scene, const std::string& size, const SynthOptions& so) const {
    auto c = std::make_unique<Case>();
    c->scene = scene;
    c->size = size;
    Progress(scene + " " + size + ": rendering the reference views");
    c->synth = MakeSynth(scene, so, o_.data);
    c->fit = c->synth.bundle;
    c->held_out = c->fit.views[1];
    c->fit.views.resize(1);
    c->tracer = std::make_unique<RayTracer>(c->fit.mesh);
    c->truth = ParseTruthLights(*c->fit.truth_json, scene + "/truth.json");
    CentreTruthLights(&c->truth, c->tracer->center());  // directions from where the estimator measures them
    for (const TruthLight& t : c->truth)
      c->near_truth = c->near_truth || (t.position && (*t.position - c->tracer->center()).norm() <
                                                          PointLightOptions{}.far * c->tracer->radius());
    for (int r : knobs_.rings) c->true_cells[r] = TrueCellRadiance(c->synth.lighting, EnvMap(r, c->fit.up));
    const EnvMap env(defaults_.rings, c->fit.up);
    c->true_cells[defaults_.rings] = TrueCellRadiance(c->synth.lighting, env);
    const std::vector<double>& true_cells = c->true_cells[defaults_.rings];
    if (!true_cells.empty()) c->relit_floor = RelitError(*c, env, {true_cells, {}}, defaults_.tracer, o_.eval_spp);
    // FD's unit of work: one render of the fitted view (same settings as a trace).
    c->render_seconds = SecondsPerCellRender(*c->tracer, env, c->fit.views, defaults_.tracer, 2);
    return c;
  }

  /// The methods' curves: fast, FD (from fast's run) and the paper's PGD, every run forced
  /// through all sMC rounds so the rounds curve is complete. Returns fast's run.
  EstimateResult RunMethods(Case* c) const {
    EstimateOptions fast = defaults_;
    fast.max_rounds = o_.quick ? 2 : 4;
    fast.change_threshold = 0;
    EstimateResult rf = RunEstimate(*c, fast);
    c->curves.push_back(MethodCurve(*c, kFast, rf, fast, o_.eval_spp));
    c->prior = rf.prior;
    c->curves.push_back(FdCurve(c->curves.back(), rf, c->render_seconds));
    Progress(Fmt("  fast %.1f s, relit error %.4f (true lighting on the cells %.4f)", rf.rounds.back().end_seconds,
                 c->curves[0].points.back().relit, c->relit_floor));
    EstimateOptions pgd = fast;
    pgd.solver = SolverKind::kGradient;
    pgd.solver_options.max_seconds = o_.quick ? 1 : o_.gradient_cap;
    const EstimateResult rg = RunEstimate(*c, pgd);
    c->curves.push_back(MethodCurve(*c, kPgd, rg, pgd, o_.eval_spp));
    Progress(Fmt("  paper PGD %.1f s", rg.rounds.back().end_seconds));
    if (c->near_truth) {  // the far-light model beside the lamps', on the same scene
      EstimateOptions alone = fast;
      alone.point_lights.max_lights = 0;
      alone.directional_lights = false;  // the map alone (a sun is sought whatever the lamps)
      const EstimateResult ra = RunEstimate(*c, alone);
      c->curves.push_back(MethodCurve(*c, kMapAlone, ra, alone, o_.eval_spp));
      Progress(Fmt("  map alone %.1f s, relit error %.4f", ra.rounds.back().end_seconds,
                   c->curves.back().points.back().relit));
    }
    return rf;
  }

  /// Knobs of the fast solver: one final point per setting; the default setting's point is
  /// the forced fast run where the default stopping rule would have stopped it.
  void SweepKnobs(Case* c, const EstimateResult& fast) const {
    const Point dflt = c->curves[0].points[DefaultStopRound(fast, defaults_.change_threshold)];
    SweepKnob(c, "spp", knobs_.spps, defaults_.tracer.spp, dflt, [](EstimateOptions* e, int v) { e->tracer.spp = v; });
    SweepKnob(c, "rings", knobs_.rings, defaults_.rings, dflt, [](EstimateOptions* e, int v) { e->rings = v; });
    SweepKnob(c, "bounces", knobs_.bounces, defaults_.tracer.bounces, dflt,
              [](EstimateOptions* e, int v) { e->tracer.bounces = v; });
    c->swept = true;
  }

  /// One knob's curve: a full default estimate per value, with `dflt` at the default `def`.
  void SweepKnob(Case* c, const std::string& knob, const std::vector<int>& values, int def, const Point& dflt,
                 void (*set)(EstimateOptions*, int)) const {
    std::vector<std::pair<int, Point>> pts = {{def, dflt}};
    for (int v : values) {
      EstimateOptions eo = defaults_;
      set(&eo, v);
      const EstimateResult r = RunEstimate(*c, eo);
      Point p = Evaluate(*c, r.env, r.lighting, r.left_out, eo.tracer, o_.eval_spp);
      p.seconds = r.rounds.back().end_seconds;
      p.fitted = r.final_relative_rmse;
      p.round = static_cast<int>(r.rounds.size());
      pts.emplace_back(v, p);
    }
    std::sort(pts.begin(), pts.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    Curve cv;
    cv.name = "fast: " + knob;
    for (auto& [v, p] : pts) {
      p.setting = knob + " " + std::to_string(v);
      cv.points.push_back(p);
    }
    c->curves.push_back(cv);
    Progress("  swept " + knob);
  }

  /// A real FD Jacobian at 9 rings, timed against the extrapolation from 2 probe renders.
  std::string CheckFdExtrapolation(const Case& c) const {
    const EnvMap env9(9, c.fit.up);
    const CellSampler uniform(env9, {}, {}, defaults_.tracer.nee_floor);
    std::vector<double> unit(3 * env9.size(), 0.0);
    const double per = SecondsPerCellRender(*c.tracer, env9, c.fit.views, defaults_.tracer, 2);
    Stopwatch all;
    for (int j = -1; j < env9.size(); ++j) {  // base render + one per cell
      std::fill(unit.begin(), unit.end(), 0.0);
      if (j >= 0) unit[3 * j] = unit[3 * j + 1] = unit[3 * j + 2] = 1;
      RenderEnvironment(*c.tracer, env9, c.fit.views, unit, uniform, defaults_.tracer, false);
    }
    return Fmt("A real FD Jacobian at 9 rings (%.0f renders) took %.1f s; the extrapolation from 2 probe "
               "renders predicted %.1f s",
               env9.size() + 1, all.Seconds(), per * (env9.size() + 1)) +
           " (" + c.scene + ", " + c.size + ").";
  }

  const ReportOptions& o_;
  const fs::path out_;
  const Stopwatch total_;
  const EstimateOptions defaults_;
  Knobs knobs_;
  Cases cases_;
  std::string fd_check_;
};

}  // namespace

Run AddBenchReport(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "bench-report", "error against run time for the solvers, the FD baseline and the knobs (report.md + PNG + CSV)");
  auto o = std::make_shared<ReportOptions>();
  o->data = DefaultDataDir();
  cmd->add_option("--out", o->out, "report directory")->capture_default_str();
  cmd->add_option("--sizes", o->sizes, "image sizes WxH")->capture_default_str();
  cmd->add_option("--scenes", o->scenes, "synthetic scenes (lightprobe synth --list)")->capture_default_str();
  cmd->add_option("--gradient-cap", o->gradient_cap, "seconds the paper's PGD may run per sMC round")
      ->capture_default_str();
  cmd->add_option("--eval-spp", o->eval_spp, "samples per pixel of the held-out relit renders")->capture_default_str();
  cmd->add_option("--synth-spp", o->synth_spp, "samples per pixel of the reference images")->capture_default_str();
  cmd->add_flag("--sweep-all-sizes", o->sweep_all_sizes, "sweep the knobs at every size (default: the first only)");
  cmd->add_flag("--quick", o->quick, "a small smoke run: fewer settings, shorter caps (for tests)");
  cmd->add_option("--data", o->data, "data directory (hdri/, mesh/; the bundled assets by default)")->capture_default_str();
  cmd->add_option("--threads", o->threads, "worker threads (0 = all cores)")->capture_default_str();
  return [o] {
    ThreadLimit limit(o->threads);
    ReportRun(*o).Run();
  };
}

}  // namespace lp::app
