// `lightprobe export`: an estimate for Blender, glTF viewers and AR engines (docs/formats.md,
// "Exports").
#include <cstdio>
#include <filesystem>

#include "app/commands.h"
#include "common/timer.h"
#include "exports/export_scene.h"

namespace lp::app {
namespace fs = std::filesystem;

Run AddExport(CLI::App& app) {
  auto* cmd = app.add_subcommand("export", "write an estimate for Blender (blender), glTF viewers (gltf) or AR engines (sh)");
  auto scene = std::make_shared<std::string>();
  auto estimate = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  cmd->add_option("SCENE_DIR", *scene, "the scene bundle the estimate was made from")->required();
  cmd->add_option("ESTIMATE_DIR", *estimate, "the estimate (its lights.json; albedo_mesh.ply when there)")->required();
  cmd->add_option("--format", *format, "blender | gltf | sh")->required();
  cmd->add_option("--out", *out, "output directory")->required();
  return [=] {
    Stopwatch sw;
    const ExportFormat f = ParseExportFormat(*format);  // the cheap input's error first
    const ExportScene s = LoadExportScene(*scene, *estimate);
    const std::vector<std::string> files = WriteExport(s, f, *out);
    std::printf("export %s: mesh from %s (%zu triangles), %zu keyframe camera(s), %s map, %zu point light(s), "
                "%zu directional light(s), %zu glowing surface(s), %zu opening(s) (%zu triangles left out)\n",
                ToString(f), s.mesh_source.c_str(), s.mesh.triangles.size(), s.cameras.size(),
                s.environment.height ? "a" : "no", OfKind<PointLight>(s.lights).size(),
                OfKind<DirectionalLight>(s.lights).size(), OfKind<EmitterLight>(s.lights).size(), s.openings,
                s.opening_triangles);
    const fs::path dir = fs::absolute(*out).lexically_normal();
    std::printf("wrote %s in %.2f s:", dir.c_str(), sw.Seconds());
    for (const std::string& name : files) std::printf(" %s", name.c_str());
    std::printf("\n");
    if (f == ExportFormat::kBlender)
      std::printf("open it: blender -b -noaudio --factory-startup --python %s -- --save scene.blend\n",
                  (dir / "scene.py").c_str());
  };
}

}  // namespace lp::app
