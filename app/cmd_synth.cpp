// `lightprobe synth`: synthetic scene bundles with ground truth.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "app/commands.h"
#include "capture/frame_source.h"
#include "capture/synth_source.h"
#include "common/atomic_file.h"
#include "common/image_io.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "estimation/synth.h"

namespace lp::app {
namespace fs = std::filesystem;


Run AddSynth(CLI::App& app) {
  auto* cmd = app.add_subcommand("synth", "write a synthetic scene bundle with known lighting (truth.json)");
  auto name = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto list = std::make_shared<bool>(false);
  auto o = std::make_shared<SynthOptions>();
  auto data = std::make_shared<std::string>(DefaultDataDir());
  auto threads = std::make_shared<int>(0);
  auto frames = std::make_shared<int>(0);
  auto min_triangles = std::make_shared<int>(0);
  cmd->add_option("--frames", *frames,
                  "write N RGB-D frames along an arc (a Redwood-layout frame directory with trajectory.log and "
                  "truth.json) "
                  "instead of a scene bundle");
  cmd->add_option("NAME", *name, "scene name (see --list)");
  cmd->add_option("--out", *out, "output scene directory");
  cmd->add_flag("--list", *list, "list the available scenes");
  cmd->add_option("--width", o->width, "image width")->capture_default_str();
  cmd->add_option("--height", o->height, "image height")->capture_default_str();
  cmd->add_option("--spp", o->spp, "samples per pixel of the reference image")->capture_default_str();
  cmd->add_option("--seed", o->seed, "random seed")->capture_default_str();
  cmd->add_option("--held-out", o->held_out_views, "extra views from another viewpoint (0 or 1), not for fitting")
      ->capture_default_str();
  cmd->add_flag("--depth-noise", o->depth_noise,
                "with --frames: structured-light depth noise and holes (Xtion-like; default exact depth)");
  cmd->add_flag("--lamps-seen", o->lamps_seen,
                "with --frames: the lamps' spheres seen by the colour camera at their radiance (clipped in the 8-bit "
                "frames) and returning no depth, as a bare bulb does");
  cmd->add_option("--data", *data, "data directory (mesh/ for frag115, hdri/ for env-*)")->capture_default_str();
  cmd->add_option("--threads", *threads, "worker threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--min-triangles", *min_triangles,
                  "split the bundle's triangles (same surface) until it has at least this many (viewer benchmark)")
      ->capture_default_str();
  return [=] {
    if (*list) {
      for (const auto& [n, d] : SynthSceneList()) std::printf("%-12s %s\n", n.c_str(), d.c_str());
      return;
    }
    if (name->empty()) throw InputError("synth: give a scene NAME (see lightprobe synth --list)");
    if (out->empty()) throw InputError("synth: --out SCENE_DIR is required");
    ThreadLimit limit(*threads);
    Stopwatch sw;
    if (*frames > 0) {
      std::string truth;
      WriteFrameDirectory(*out, ToRgbdFrames(RenderSynthFrames(*name, *o, *data, *frames, &truth)));
      if (!truth.empty()) WriteTextAtomically(fs::path(*out) / "truth.json", truth);
      std::printf("wrote %d synthetic RGB-D frames of '%s' (%dx%d, %d spp) to %s in %.1f s\n", *frames, name->c_str(),
                  o->width, o->height, o->spp, fs::absolute(*out).lexically_normal().c_str(), sw.Seconds());
      return;
    }
    SceneBundle b = MakeSynthScene(*name, *o, *data);
    if (*min_triangles > 0) b.mesh = RefineMesh(b.mesh, *min_triangles);
    WriteSceneBundle(*out, b);
    std::printf("wrote synthetic scene '%s' (%dx%d, %d spp) to %s in %.1f s\n", name->c_str(), o->width, o->height,
                o->spp, fs::absolute(*out).lexically_normal().c_str(), sw.Seconds());
  };
}

}  // namespace lp::app
