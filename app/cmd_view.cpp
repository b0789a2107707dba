// `lightprobe` / `lightprobe view [INPUT]`: the window (ui/). The app gives the viewer the
// bundled demo and the estimate writer; the viewer drives the stages through its session.
#include <filesystem>

#include "app/commands.h"
#include "calibration/calibration.h"
#include "ui/viewer.h"

namespace lp::app {
namespace fs = std::filesystem;

std::string DemoRecording() {
  const char* env = std::getenv("LIGHTPROBE_DEMO");
  if (env && *env) return env;
#ifdef LIGHTPROBE_SOURCE_DIR
  return (fs::path(LIGHTPROBE_SOURCE_DIR) / "assets" / "demo-recording" / "demo.oni").string();
#else
  return "assets/demo-recording/demo.oni";
#endif
}

ui::ViewerOptions DefaultViewerOptions() {
  ui::ViewerOptions o;
  o.session.demo_input = DemoRecording();
  o.session.write_estimate = [](const std::string& dir, const SceneBundle& bundle, const EstimateOptions& options,
                                const EstimateResult& result) {
    WriteEstimateOutputs(dir, bundle, options, result, result.total_seconds);
  };
  // The window is interactive: the relit keyframes are the fit until the job's clean render
  // has its first pass (EstimateJob::CleanRender).
  o.estimate.render_spp = 0;
  o.session.live = true;  // the lights follow the scan
  return o;
}

Run AddView(CLI::App& app) {
  auto* cmd = app.add_subcommand("view", "the window: live previews, reconstruction, Estimate, the lit mesh "
                                         "(also what `lightprobe` without arguments opens)");
  auto o = std::make_shared<ui::ViewerOptions>(DefaultViewerOptions());
  cmd->add_option("INPUT", o->input,
                  "camera[:URI], demo, an .oni file, a frame directory or a scene bundle (default: an attached "
                  "camera, else the bundled demo recording)");
  cmd->add_option("--script", o->script, "a command file to run in the window (tests, benchmarks; docs/viewer.md)");
  cmd->add_option("--size", o->width, "window width (the height is 9/16 of it)")->capture_default_str();
  cmd->add_option("--rings", o->estimate.rings, "the Estimate panel's default rings")->capture_default_str();
  cmd->add_option("--live", o->session.live,
                  "1: estimate by itself while a camera or a file is reconstructed (the panel's live switch), 0: "
                  "only when Estimate is pressed")
      ->capture_default_str();
  auto calibration = std::make_shared<std::string>();
  cmd->add_option("--calibration", *calibration,
                  "calibration file (lightprobe calibrate) for the reconstruction, as reconstruct takes it");
  auto intrinsics = std::make_shared<std::string>();
  cmd->add_option("--intrinsics", *intrinsics, kIntrinsicsHelp);
  return [o, calibration, intrinsics] {
    ui::ViewerOptions v = *o;
    if (!calibration->empty()) {
      v.session.reconstruction.reconstruction.calibration = ReadCalibration(*calibration);
      v.session.reconstruction.calibrated = true;
    }
    if (!intrinsics->empty()) UseIntrinsicsFile(&v.session.reconstruction.reconstruction.calibration, *intrinsics);
    v.height = v.width * 9 / 16;
    const int code = ui::RunViewer(v);
    if (code != 0) throw InputError("the viewer's script failed (see above)");
  };
}

}  // namespace lp::app
