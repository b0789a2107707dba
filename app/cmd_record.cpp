// `lightprobe record`: depth + colour through OpenNI2's Recorder into an .oni file, from a
// live device or any OpenNI2 source (lpsynth://DIR serves a frame directory as a device).
#include <cstdio>
#include <filesystem>

#include "app/commands.h"
#include "capture/openni.h"
#include "common/error.h"

namespace lp::app {

Run AddRecord(CLI::App& app) {
  auto* cmd = app.add_subcommand("record", "record depth + colour from an OpenNI2 device into an .oni file");
  auto out = std::make_shared<std::string>();
  auto o = std::make_shared<RecordOptions>();
  o->frames = 0;
  o->seconds = 5;
  auto frames = std::make_shared<int>(0);
  cmd->add_option("--out", *out, "the .oni file to write (replaced only when the recording is complete)")->required();
  cmd->add_option("--seconds", o->seconds, "how long to record")->capture_default_str();
  cmd->add_option("--frames", *frames, "record this many depth frames instead of --seconds");
  cmd->add_option("--source", o->uri,
                  "OpenNI2 device URI (default: the first camera; lpsynth://DIR serves a frame directory)");
  cmd->add_flag("--lossy-color", o->lossy_color, "store colour as JPEG (smaller; default uncompressed)");
  cmd->add_option("--width", o->width, "stream width (640 or 320 on an Xtion; default: the device's mode)");
  cmd->add_option("--height", o->height, "stream height (480 or 240)");
  cmd->add_option("--exposure", o->exposure, "colour exposure in device units (default: as the device has it)");
  cmd->add_option("--gain", o->gain, "colour gain in device units");
  auto auto_exposure = std::make_shared<bool>(false);
  cmd->add_flag("--auto-exposure", *auto_exposure,
                "leave auto exposure / white balance on (default: locked, as photometric work needs)");
  return [=] {
    RecordOptions ro = *o;
    if (*frames > 0) ro.frames = *frames;
    ro.lock_exposure = !*auto_exposure;
    if ((ro.width > 0) != (ro.height > 0)) throw InputError("record: give both --width and --height");
    const RecordResult r = RecordOni(*out, ro);
    std::printf("recorded %d depth and %d colour frames in %.1f s to %s\n", r.depth_frames, r.color_frames, r.seconds,
                std::filesystem::absolute(*out).lexically_normal().c_str());
    const CameraControls& c = r.controls;
    if (c.camera_settings)
      std::printf("colour: exposure %d, gain %d, auto exposure %s, auto white balance %s; depth %sregistered (in %s)\n",
                  c.exposure, c.gain, c.auto_exposure ? "on" : "off", c.auto_white_balance ? "on" : "off",
                  c.registered ? "" : "not ", OniSideFile(*out).c_str());
  };
}

}  // namespace lp::app
