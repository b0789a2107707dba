// `lightprobe render`: relight every view of a scene bundle under a given environment.
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "app/commands.h"
#include "common/image_io.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "estimation/path_tracer.h"
#include "scene/ray_tracer.h"

namespace lp::app {
namespace fs = std::filesystem;

Run AddRender(CLI::App& app) {
  auto* cmd = app.add_subcommand("render", "forward render (relight) every view of a scene under an environment");
  auto scene = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto envmap = std::make_shared<std::string>();
  auto uniform = std::make_shared<std::string>();
  auto rings = std::make_shared<int>(61);
  auto threads = std::make_shared<int>(0);
  auto o = std::make_shared<TracerOptions>();
  cmd->add_option("SCENE_DIR", *scene, "scene bundle directory")->required();
  cmd->add_option("--out", *out, "output directory")->required();
  auto* e = cmd->add_option("--envmap", *envmap, "equirectangular linear .exr/.hdr (convention: docs/formats.md)");
  auto* u = cmd->add_option("--uniform", *uniform, "uniform environment radiance R,G,B");
  e->excludes(u);
  cmd->add_option("--rings", *rings, "rings used to discretize --envmap")->capture_default_str();
  cmd->add_option("--spp", o->spp, "samples per pixel")->capture_default_str();
  cmd->add_option("--bounces", o->bounces, "surface interactions per path")->capture_default_str();
  cmd->add_option("--seed", o->seed, "random seed")->capture_default_str();
  cmd->add_option("--threads", *threads, "worker threads (0 = all cores)")->capture_default_str();
  return [=] {
    if (envmap->empty() == uniform->empty()) throw InputError("render: give exactly one of --envmap or --uniform");
    Stopwatch sw;
    ThreadLimit limit(*threads);
    SceneBundle b = LoadSceneBundle(*scene);
    EnvMap env(*rings, b.up);
    std::vector<double> lambda;
    if (!uniform->empty()) {
      std::vector<double> rgb;
      std::stringstream ss(*uniform);
      std::string tok;
      while (std::getline(ss, tok, ',')) {
        try {
          rgb.push_back(std::stod(tok));
        } catch (...) {
          throw InputError("--uniform: expected three numbers R,G,B, got '" + *uniform + "'");
        }
      }
      if (rgb.size() != 3 || !(rgb[0] >= 0 && rgb[1] >= 0 && rgb[2] >= 0))
        throw InputError("--uniform: expected three non-negative numbers R,G,B, got '" + *uniform + "'");
      for (int j = 0; j < env.size(); ++j) lambda.insert(lambda.end(), rgb.begin(), rgb.end());
    } else {
      const fs::path p(*envmap);
      ImageRGB map = p.extension() == ".hdr" ? ReadHdr(p) : ReadImageLinear(p);
      if (map.width != 2 * map.height) throw InputError(*envmap, "environment map must be equirectangular (width = 2*height)");
      for (float v : map.data)
        if (!std::isfinite(v) || v < 0) throw InputError(*envmap, "environment map has negative or non-finite values");
      lambda = env.FromEquirect(map);
    }
    RayTracer tracer(b.mesh);
    CellSampler sampler(env, lambda, {}, 0.2);
    std::vector<ImageRGB> imgs = RenderEnvironment(tracer, env, b.views, lambda, sampler, *o, true);
    for (std::size_t k = 0; k < imgs.size(); ++k) {
      const std::string name = "render_view" + std::to_string(k);
      WriteExr(fs::path(*out) / (name + ".exr"), imgs[k]);
      WritePngSrgb(fs::path(*out) / (name + ".png"), imgs[k]);
    }
    std::printf("rendered %zu view(s) in %.2f s; results in %s\n", imgs.size(), sw.Seconds(),
                fs::absolute(*out).lexically_normal().c_str());
  };
}

}  // namespace lp::app
