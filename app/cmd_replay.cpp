// `lightprobe replay`: reads an .oni recording or a frame directory through the same
// FrameSource path as live capture; prints what it holds and the replay rate, and can
// write the frames out as a frame directory.
#include <cstdio>
#include <filesystem>
#include <optional>

#include "app/commands.h"
#include "calibration/calibration.h"
#include "capture/frame_source.h"
#include "capture/openni.h"
#include "common/timer.h"

namespace lp::app {
namespace fs = std::filesystem;

namespace {

/// The frame's colour camera (and its depth camera, when depth is registered to colour)
/// from an intrinsics file.
void UseIntrinsics(const CameraModel& k, const std::string& file, RgbdFrame* f) {
  if (k.width != f->color.width || k.height != f->color.height)
    throw InputError(file, "intrinsics for " + std::to_string(k.width) + "x" + std::to_string(k.height) +
                               ", but the colour frames are " + std::to_string(f->color.width) + "x" +
                               std::to_string(f->color.height));
  f->color_intrinsics = k;
  if (f->registered && f->depth.width == k.width && f->depth.height == k.height) f->depth_intrinsics = k;
}

}  // namespace

Run AddReplay(CLI::App& app) {
  auto* cmd = app.add_subcommand("replay", "replay an .oni file or a frame directory (info, rate, export)");
  auto source = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto real_time = std::make_shared<bool>(false);
  auto start = std::make_shared<int>(0);
  auto count = std::make_shared<int>(0);
  cmd->add_option("SOURCE", *source, ".oni file or frame directory (TUM, Redwood, joinMap)")->required();
  cmd->add_flag("--real-time", *real_time, ".oni: play at the recorded rate (default: as fast as possible)");
  cmd->add_option("--start", *start, "skip this many frames first (seek)")->capture_default_str();
  cmd->add_option("--frames", *count, "stop after this many frames (0 = all)")->capture_default_str();
  cmd->add_option("--out", *out, "write the frames as a frame directory (color/, depth/ in mm, intrinsics)");
  auto intrinsics = std::make_shared<std::string>();
  cmd->add_option("--intrinsics", *intrinsics, kIntrinsicsHelp);
  return [=] {
    std::optional<CameraModel> k;
    if (!intrinsics->empty()) k = ReadIntrinsicsFile(*intrinsics);
    std::unique_ptr<FrameSource> src = OpenFrameSource(*source, *real_time);
    std::printf("%s%s\n", src->Describe().c_str(), k ? ("; colour intrinsics from " + *intrinsics).c_str() : "");
    RgbdFrame f;
    if (*start > 0) src->Seek(*start);  // OpenNI2's seek crashes: the source skips frames instead
    std::vector<RgbdFrame> kept;
    Stopwatch sw;
    int n = 0;
    double valid = 0;
    SourceStatus status = SourceStatus::kFrame;
    while ((*count == 0 || n < *count) && (status = src->Next(&f, 5.0)) == SourceStatus::kFrame) {
      std::size_t v = 0;
      if (k) UseIntrinsics(*k, *intrinsics, &f);
      for (auto d : f.depth.data) v += d != 0;
      valid += f.depth.pixels() ? static_cast<double>(v) / f.depth.pixels() : 0;
      if (n == 0)
        std::printf("depth %dx%d, colour %dx%d, fx %.1f, %s\n", f.depth.width, f.depth.height, f.color.width,
                    f.color.height, f.color_intrinsics.fx, f.registered ? "registered" : "not registered");
      if (!out->empty()) kept.push_back(f);
      ++n;
    }
    const double s = sw.Seconds();
    std::printf("%d frames in %.2f s (%.0f frames/s), %.0f %% of depth pixels valid on average; stopped: %s\n", n, s,
                s > 0 ? n / s : 0.0, n ? 100 * valid / n : 0.0,
                (*count != 0 && n == *count) ? "--frames reached" : ToString(status));
    if (status == SourceStatus::kDeviceLost) throw InputError(*source, "the device went away");
    if (!out->empty()) {
      if (kept.empty()) throw InputError(*source, "no frames to write");
      WriteFrameDirectory(*out, kept);
      std::printf("wrote %zu frames to %s\n", kept.size(), fs::absolute(*out).lexically_normal().c_str());
    }
  };
}

}  // namespace lp::app
