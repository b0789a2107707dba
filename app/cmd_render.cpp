// `lightprobe render`: relight every view of a scene bundle under a given environment, or
// under an estimate's lights.json (map, point lights and directional lights).
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "app/commands.h"
#include "common/image_io.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "common/atomic_file.h"
#include "estimation/lights_file.h"
#include "estimation/path_tracer.h"
#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "estimation/truth.h"
#include "scene/mesh.h"
#include "scene/ray_tracer.h"

namespace lp::app {
namespace fs = std::filesystem;

namespace {

/// An equirectangular map file as per-cell radiance of `env`.
std::vector<double> ReadEnvironment(const std::string& file, const EnvMap& env) {
  return env.FromEquirect(ReadEquirectMap(file));
}

std::vector<double> ParseUniform(const std::string& text, const EnvMap& env) {
  std::vector<double> rgb;
  std::stringstream ss(text);
  std::string tok;
  while (std::getline(ss, tok, ',')) {
    try {
      rgb.push_back(std::stod(tok));
    } catch (...) {
      throw InputError("--uniform: expected three numbers R,G,B, got '" + text + "'");
    }
  }
  if (rgb.size() != 3 || !(rgb[0] >= 0 && rgb[1] >= 0 && rgb[2] >= 0))
    throw InputError("--uniform: expected three non-negative numbers R,G,B, got '" + text + "'");
  std::vector<double> lambda;
  for (int j = 0; j < env.size(); ++j) lambda.insert(lambda.end(), rgb.begin(), rgb.end());
  return lambda;
}

}  // namespace

Run AddRender(CLI::App& app) {
  auto* cmd = app.add_subcommand("render", "forward render (relight) every view of a scene under an environment");
  auto scene = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto envmap = std::make_shared<std::string>();
  auto uniform = std::make_shared<std::string>();
  auto lights = std::make_shared<std::string>();
  auto mesh = std::make_shared<std::string>();
  auto rings = std::make_shared<int>(61);
  auto threads = std::make_shared<int>(0);
  auto o = std::make_shared<TracerOptions>();
  o->bounces = kRenderBounces;  // a relight without the estimator's cap (docs/method.md)
  cmd->add_option("SCENE_DIR", *scene, "scene bundle directory")->required();
  cmd->add_option("--out", *out, "output directory")->required();
  auto* e = cmd->add_option("--envmap", *envmap, "equirectangular linear .exr/.hdr (convention: docs/formats.md)");
  auto* u = cmd->add_option("--uniform", *uniform, "uniform environment radiance R,G,B");
  auto* l = cmd->add_option("--lights", *lights, "an estimate's lights.json: its map, point lights and directional lights");
  e->excludes(u);
  l->excludes(e);
  l->excludes(u);
  cmd->add_option("--mesh", *mesh,
                  "a PLY mesh in place of the bundle's (default with --lights: the estimate's albedo_mesh.ply beside "
                  "it, when there is one)");
  cmd->add_option("--rings", *rings, "rings used to discretize --envmap")->capture_default_str();
  cmd->add_option("--spp", o->spp, "samples per pixel")->capture_default_str();
  cmd->add_option("--bounces", o->bounces, "surface interactions per path")->capture_default_str();
  cmd->add_option("--seed", o->seed, "random seed")->capture_default_str();
  cmd->add_option("--threads", *threads, "worker threads (0 = all cores)")->capture_default_str();
  return [=] {
    if (envmap->empty() + uniform->empty() + lights->empty() != 2)
      throw InputError("render: give exactly one of --envmap, --uniform or --lights");
    Stopwatch sw;
    ThreadLimit limit(*threads);
    LightsFile file;  // read first: the cheap input's errors come before the bundle's work
    if (!lights->empty()) file = ReadLightsFile(*lights);
    SceneBundle b = LoadSceneBundle(*scene);
    // An estimate's lights go with the albedo it was made under: its albedo_mesh.ply beside
    // lights.json, when it wrote one (refined or scaled), unless --mesh names another.
    std::string mesh_file = *mesh;
    const fs::path beside = fs::path(*lights).parent_path() / "albedo_mesh.ply";
    if (mesh_file.empty() && !lights->empty() && fs::exists(beside)) {
      mesh_file = beside.string();
      std::printf("mesh: %s (the albedo the estimate was made under; --mesh to use another)\n", mesh_file.c_str());
    }
    if (!mesh_file.empty()) b.mesh = ReadPly(mesh_file);
    EnvMap env(*rings, b.up);
    std::vector<double> lambda;
    if (!uniform->empty()) lambda = ParseUniform(*uniform, env);
    if (!envmap->empty()) lambda = ReadEnvironment(*envmap, env);
    if (!lights->empty()) {
      if (!file.environment.empty())
        lambda = ReadEnvironment((fs::path(*lights).parent_path() / file.environment).string(), env);
    }
    RayTracer tracer(b.mesh, TrianglesOnShapes(b.mesh, file.openings));  // (a window's opening: no surface)
    // The map and the lights on the same paths (a lights.json without a map: a dark one;
    // with nothing at all, everything is black).
    if (lambda.empty()) lambda.assign(3 * env.size(), 0.0);
    const CellSampler sampler(env, lambda, {}, 0.2);
    const std::vector<ImageRGB> imgs =
        RenderLighting(tracer, env, {lambda, file.lights}, sampler, b.views, *o, true);
    for (std::size_t k = 0; k < imgs.size(); ++k) {
      const std::string name = "render_view" + std::to_string(k);
      WriteExr(fs::path(*out) / (name + ".exr"), imgs[k]);
      WritePngSrgb(fs::path(*out) / (name + ".png"), imgs[k]);
      const double err = RelativeImageRmse(imgs[k], b.views[k].image, b.views[k].valid);
      if (std::isfinite(err)) std::printf("view %zu: relative RMSE against the bundle's image %.4f\n", k, err);
    }
    std::printf("rendered %zu view(s) in %.2f s; results in %s\n", imgs.size(), sw.Seconds(),
                fs::absolute(*out).lexically_normal().c_str());
  };
}

}  // namespace lp::app
