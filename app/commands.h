#pragma once
/// Subcommands of the lightprobe executable. Each Add* registers its options on
/// `app` and returns the callback that runs it.
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "estimation/estimator.h"
#include "estimation/path_tracer.h"
#include "reconstruction/live_trigger.h"
#include "reconstruction/reconstruction_run.h"
#include "ui/viewer.h"

namespace lp::app {

using Run = std::function<void()>;

Run AddEstimate(CLI::App& app);
Run AddRender(CLI::App& app);
Run AddSynth(CLI::App& app);
Run AddBench(CLI::App& app);
Run AddBenchReport(CLI::App& app);
Run AddDevices(CLI::App& app);
Run AddRecord(CLI::App& app);
Run AddReplay(CLI::App& app);
Run AddReconstruct(CLI::App& app);
Run AddCalibrate(CLI::App& app);
Run AddView(CLI::App& app);
Run AddExport(CLI::App& app);
Run AddEvaluate(CLI::App& app);

/// The window's defaults: the bundled demo recording (LIGHTPROBE_DEMO overrides it) and
/// the estimate writer for Export.
ui::ViewerOptions DefaultViewerOptions();

/// --intrinsics' help, the same for reconstruct, --headless, replay and view.
inline constexpr const char* kIntrinsicsHelp =
    "colour camera intrinsics (JSON: a calibration file's \"camera\" section, docs/formats.md) instead of the "
    "recording's; a --calibration file's win over these";

/// What `reconstruct` (and `--headless`) take besides the input and the output.
struct ReconstructSettings {
  ReconstructionOptions options;
  float truncation = 0;  ///< 0 = 4 voxels
  int max_frames = 0;    ///< 0 = all
  std::string poses, calibration, intrinsics;  ///< files; "" = none
  int threads = 0;
};
/// Registers reconstruct's options (shared with --headless).
void AddReconstructOptions(CLI::App& cmd, ReconstructSettings* settings);
/// The run's options from the settings: the calibration and pose files read, truth.json
/// beside `input` when there is one.
ReconstructionRunOptions MakeRunOptions(const ReconstructSettings& settings, const std::string& input);
/// Reconstructs `input` (an .oni recording or a frame directory) into the bundle `out`,
/// with progress on stderr and a summary on stdout.
void Reconstruct(const std::string& input, const std::string& out, const ReconstructSettings& settings);
/// `--headless --live`'s settings.
struct LiveSettings {
  double speed = 1;  ///< times the recorded rate (0: as fast as frames are processed, none dropped)
  /// The estimates while it plays are previews (LivePreview), and the whole scan gets a
  /// preview before its full estimate; false: every estimate full.
  bool preview = true;
  LiveTriggerOptions trigger;
};
/// `lightprobe --headless INPUT --out DIR --live`: the input played at its recorded rate,
/// reconstructed, and estimated while it plays (app/headless_live.cpp).
void RunLive(const std::string& input, const std::string& out, const ReconstructSettings& settings,
             const LiveSettings& live);
/// `lightprobe --headless INPUT --out DIR ...` (args without the program name).
int RunHeadless(const std::vector<std::string>& args);

/// One row of `lightprobe bench`'s table: size, method, seconds, relative RMSE, light error, note.
using BenchRow = std::function<void(const std::string&, const std::string&, double, double, double, const std::string&)>;

/// The reconstruction part of `lightprobe bench` (bench_reconstruction.cpp).
void ReconstructionBench(const BenchRow& row);

/// Registers the estimator options shared by estimate and bench.
void AddEstimateOptions(CLI::App& cmd, EstimateOptions* o, int* threads);

/// Writes every output of an estimate into out_dir (atomically per file); `lights_written`:
/// WriteEstimateLights already wrote its part (not written again).
void WriteEstimateOutputs(const std::string& out_dir, const SceneBundle& bundle, const EstimateOptions& options,
                          const EstimateResult& result, double command_seconds, bool lights_written = false);

/// The lights and what they go with into out_dir (atomically per file): envmap.exr (.png,
/// _directions.csv), albedo_mesh.ply, emitters.ply and openings.ply, then lights.json, which
/// names them (a reader that finds it finds them). What EstimateOptions::on_lights writes.
void WriteEstimateLights(const std::string& out_dir, const SceneBundle& bundle, const EstimateResult& result);

/// Seconds of one render of `views` with one cell lit (the finite-difference baseline's
/// unit of work; the same paths as a trace of A), averaged over `probes` renders.
double SecondsPerCellRender(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                            const TracerOptions& tracer, int probes);

/// A number for CSV files: %.9g, empty for NaN.
std::string Num(double v);

/// Where the bundled data lives: LIGHTPROBE_DATA, else the source tree's assets/ (hdri/, mesh/, rgbd/).
std::string DefaultDataDir();

}  // namespace lp::app
