// `lightprobe --headless INPUT --out DIR`: the whole pipeline without a window: reconstruct
// INPUT into DIR/scene (the same run, with the same options, as `reconstruct`), then
// estimate its lighting into DIR/estimate with the `estimate` subcommand's defaults.
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "app/commands.h"

namespace lp::app {

namespace {

/// Parses `args` (without the program name) as one subcommand of a fresh app and runs it.
/// Parses `args` as `add`'s subcommand on `app` (which must outlive the result): its errors
/// one line, before any work; returns what runs it.
Run ParseSubcommand(CLI::App* app, Run (*add)(CLI::App&), const std::vector<std::string>& args) {
  app->require_subcommand(1);
  const Run run = add(*app);
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them reversed
  try {
    app->parse(reversed);
  } catch (const CLI::ParseError& e) {
    throw InputError(std::string("--headless: ") + e.what());
  }
  return run;
}

}  // namespace

int RunHeadless(const std::vector<std::string>& args) {
  CLI::App app{"the whole pipeline without a window"};
  std::string input, out;
  ReconstructSettings settings;
  // Offline nothing has to keep up with a camera: fuse every frame (less noise) unless told.
  settings.options.fuse_every = 1;
  app.add_option("--headless", input, "an .oni recording or a frame directory")->required();
  app.add_option("--out", out, "DIR/scene (the bundle) and DIR/estimate (the lighting)")->required();
  AddReconstructOptions(app, &settings);
  std::string estimate_options;
  app.add_option("--estimate-options", estimate_options,
                 "estimate's options for the run, in one quoted string (e.g. \"--seed 2 --render-noise 0\"); not with "
                 "--live");
  bool live = false;
  LiveSettings live_settings;
  app.add_flag("--live", live,
               "estimate while the input plays at its recorded rate: each finished estimate in DIR/live/NNN/, the "
               "latest in DIR/estimate, live.csv logging them");
  app.add_option("--live-speed", live_settings.speed, "with --live: times the recorded rate (0: as fast as read)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--live-preview", live_settings.preview,
                 "with --live: 1 = the estimates while it plays are previews (round 1 alone, seconds on one core) and "
                 "the whole scan gets one before its full estimate; 0 = every estimate full")
      ->capture_default_str();
  app.add_option("--live-growth", live_settings.trigger.growth,
                 "with --live: a new estimate once the model grew by this share of its voxel blocks")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--live-travel", live_settings.trigger.travel,
                 "with --live: ... or the camera moved this far (m, plus 0.5 m per radian turned)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them reversed
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    throw InputError(std::string("--headless: ") + e.what() +
                     " (usage: lightprobe --headless INPUT --out DIR [reconstruct's options: --poses FILE, "
                     "--calibration FILE, --voxel M, --keyframes N, ...] [--estimate-options \"estimate's options\"])");
  }
  if (live && !estimate_options.empty()) throw InputError("--headless: --estimate-options is not taken with --live");
  if (live) {
    if (!app.count("--fuse-every")) settings.options.fuse_every = ReconstructionOptions{}.fuse_every;  // a camera's pace
    RunLive(input, out, settings, live_settings);
    return 0;
  }
  const std::string scene = (std::filesystem::path(out) / "scene").string();
  const std::string estimate = (std::filesystem::path(out) / "estimate").string();
  std::vector<std::string> estimate_args = {"estimate", scene, "--out", estimate};
  std::istringstream words(estimate_options);
  for (std::string w; words >> w;) estimate_args.push_back(w);
  CLI::App estimate_app;
  const Run run_estimate = ParseSubcommand(&estimate_app, &AddEstimate, estimate_args);  // (a bad one before the work)
  Reconstruct(input, scene, settings);
  run_estimate();
  std::printf("headless pipeline done: %s (scene bundle), %s (lighting)\n", scene.c_str(), estimate.c_str());
  return 0;
}

}  // namespace lp::app
