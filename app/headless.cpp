// `lightprobe --headless INPUT --out DIR`: the whole pipeline without a window: reconstruct
// INPUT into DIR/scene, then estimate its lighting into DIR/estimate, by running the
// `reconstruct` and `estimate` subcommands one after the other.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "app/commands.h"

namespace lp::app {

namespace {

/// Parses `args` (without the program name) as one subcommand of a fresh app and runs it.
void RunSubcommand(Run (*add)(CLI::App&), const std::vector<std::string>& args) {
  CLI::App app;
  app.require_subcommand(1);
  const Run run = add(app);
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them reversed
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    throw InputError(std::string("--headless: ") + e.what());
  }
  run();
}

}  // namespace

int RunHeadless(const std::vector<std::string>& args) {
  std::string input, out;
  std::vector<std::string> extra;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= args.size()) throw InputError("--headless: " + a + " needs a value");
      return args[++i];
    };
    if (a == "--headless") input = value();
    else if (a == "--out") out = value();
    else if (a == "--poses" || a == "--calibration" || a == "--voxel" || a == "--keyframes" || a == "--albedo" ||
             a == "--smooth" || a == "--fuse-every") {
      extra.push_back(a);
      extra.push_back(value());
    } else throw InputError("--headless: unknown argument " + a +
                            " (usage: lightprobe --headless INPUT --out DIR [--poses FILE] [--calibration FILE] "
                            "[--voxel M] [--keyframes N] [--albedo 0|1] [--smooth N] [--fuse-every N])");
  }
  if (input.empty() || out.empty()) throw InputError("--headless: usage: lightprobe --headless INPUT --out DIR");
  const std::string scene = (std::filesystem::path(out) / "scene").string();
  const std::string estimate = (std::filesystem::path(out) / "estimate").string();
  std::vector<std::string> rec = {"reconstruct", input, "--out", scene};
  // Offline nothing has to keep up with a camera: fuse every frame (less noise) unless told.
  if (std::find(extra.begin(), extra.end(), "--fuse-every") == extra.end()) {
    rec.push_back("--fuse-every");
    rec.push_back("1");
  }
  rec.insert(rec.end(), extra.begin(), extra.end());
  RunSubcommand(&AddReconstruct, rec);
  RunSubcommand(&AddEstimate, {"estimate", scene, "--out", estimate});
  std::printf("headless pipeline done: %s (scene bundle), %s (lighting)\n", scene.c_str(), estimate.c_str());
  return 0;
}

}  // namespace lp::app
