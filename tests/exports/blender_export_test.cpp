// The Blender and glTF exports as a user opens them: Debian's Blender builds the scene from
// the export (scene.py, saved as a .blend and rendered from it; scene.gltf through Blender's
// own glTF importer), Cycles renders keyframe 0, and the picture must match lightprobe's own
// render of that view under the same lights.json: an independent renderer reading the files,
// so a wrong axis, mirror, unit or camera convention in an export shows as a different image.
// The lights: a map (a sky brighter towards the zenith and one bright patch off to one side,
// so that a mirror or a turn of the map moves light), a lamp and a sun.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/atomic_file.h"
#include "common/image_io.h"
#include "estimation/envmap.h"
#include "estimation/lights/emitter_light.h"
#include "estimation/lights_file.h"
#include "estimation/light_fit.h"
#include "estimation/light_render.h"
#include "estimation/lights/light.h"
#include "estimation/synth.h"
#include "estimation/truth.h"
#include "exports/export_scene.h"
#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

constexpr int kCyclesSamples = 64;

fs::path Scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("lp_blender_export_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

/// The map of the estimate (EnvMap's convention around +Z): 32 x 64.
ImageRGB TestMap() {
  ImageRGB map(64, 32);
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const double theta = (y + 0.5) / map.height * 3.14159265358979;
      const float sky = static_cast<float>(0.04 + 0.08 * std::max(0.0, std::cos(theta)));
      float* p = map.at(x, y);
      p[0] = 0.8f * sky, p[1] = 0.9f * sky, p[2] = sky;
      if (x >= 10 && x < 14 && y >= 8 && y < 12) p[0] = 5.f, p[1] = 4.f, p[2] = 3.f;  // azimuth ~65 deg, 53 deg from up
    }
  return map;
}

/// A scene bundle (the lamp-and-sky room, 80 x 60) and an estimate directory beside it.
struct Fixture {
  fs::path root, scene, estimate;
  LightsFile lights;
  /// `real_camera`: keyframe 0 gets a principal point off the centre and pixels 8 % taller
  /// than wide, as a real colour camera's calibration has (glTF cannot carry them). `turn`:
  /// the whole bundle and its lights turned (its up no longer +Z, as a reconstruction's).
  Fixture(const std::string& name, bool real_camera, const Eigen::Matrix3d& turn = Eigen::Matrix3d::Identity(),
          bool with_sun = true)
      : root(Scratch(name)), scene(root / "scene"), estimate(root / "estimate") {
    SynthOptions o;
    o.width = 80, o.height = 60, o.spp = 1;
    SceneBundle b = MakeSynthScene("lamp-and-sky", o, fs::path(LIGHTPROBE_SOURCE_DIR) / "assets");
    if (real_camera) {
      Camera& c = b.views[0].camera;
      c.cx += 3.5, c.cy -= 2.25, c.fy = 1.08 * c.fx;
    }
    const Eigen::Matrix3f turn_f = turn.cast<float>();
    for (Eigen::Vector3f& p : b.mesh.positions) p = turn_f * p;
    for (Eigen::Vector3f& n : b.mesh.normals) n = turn_f * n;
    for (View& v : b.views) v.camera.world_from_camera.topRows<3>() = turn * v.camera.world_from_camera.topRows<3>();
    b.up = turn * b.up;
    WriteSceneBundle(scene, b);
    fs::create_directories(estimate);
    WriteExr(estimate / "envmap.exr", TestMap());
    lights.environment = "envmap.exr";
    PointLight lamp;
    lamp.position = turn * Eigen::Vector3d(1.77, 1.67, 1.75), lamp.intensity = {2.4, 2.2, 1.9}, lamp.radius = 0.05;
    lights.lights.push_back(lamp);
    DirectionalLight sun;
    sun.direction = turn * Eigen::Vector3d(-0.5, 0.3, 0.8).normalized(), sun.irradiance = {0.5, 0.45, 0.35};
    sun.angular_radius = 0.01;
    if (with_sun) lights.lights.push_back(sun);
    WriteTextAtomically(estimate / "lights.json", LightsJson(lights));
  }
  ~Fixture() { fs::remove_all(root); }

  /// lightprobe's render of keyframe 0 under the estimate (as `render --lights` makes it).
  ImageRGB OurRender(std::uint64_t seed) const {
    const SceneBundle b = LoadSceneBundle(scene);
    const EnvMap env(61, b.up);
    const std::vector<double> lambda = env.FromEquirect(TestMap());
    const RayTracer tracer(b.mesh);
    const CellSampler sampler(env, lambda, {}, 0.2);
    TracerOptions t;
    t.spp = 512, t.bounces = 12, t.seed = seed;
    return RenderLighting(tracer, env, {lambda, lights.lights}, sampler, {b.views[0]}, t, true)[0];
  }
};

/// Runs Debian's Blender in the background (in folder `cwd` when given); its output goes to `log`.
void RunBlender(const std::string& args, const fs::path& log, const fs::path& cwd = {}) {
  const std::string cmd = (cwd.empty() ? "" : "cd '" + cwd.string() + "' && ") +
                          "blender -b -noaudio --factory-startup --python-exit-code 3 " + args + " > '" +
                          log.string() + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream in(log);
  std::stringstream text;
  text << in.rdbuf();
  ASSERT_EQ(rc, 0) << "blender failed (scripts/install-deps.sh installs it): " << cmd << "\n" << text.str();
}

double Rmse(const ImageRGB& a, const ImageRGB& b) {
  return RelativeImageRmse(a, b, std::vector<std::uint8_t>(a.pixels(), 1));
}

/// Cycles' two renders (seeds 1 and 2) against lightprobe's two: the error beyond the four
/// renders' noise (each pair's difference is its noise times sqrt 2) under `limit`.
void ExpectSamePicture(const ImageRGB& cycles1, const ImageRGB& cycles2, const Fixture& f, double limit = 0.05) {
  ASSERT_EQ(cycles1.width, 80);
  ASSERT_EQ(cycles1.height, 60);
  const ImageRGB ours1 = f.OurRender(1), ours2 = f.OurRender(2);
  const double noise_cycles = Rmse(cycles1, cycles2) / std::sqrt(2.0), noise_ours = Rmse(ours1, ours2) / std::sqrt(2.0);
  const double error = Rmse(cycles1, ours1);
  const double beyond = std::sqrt(std::max(0.0, error * error - noise_cycles * noise_cycles - noise_ours * noise_ours));
  double mean_c = 0, mean_o = 0;
  for (std::size_t i = 0; i < cycles1.data.size(); ++i) mean_c += cycles1.data[i], mean_o += ours1.data[i];
  std::printf("relative RMSE %.4f (noise: Cycles %.4f, lightprobe %.4f); beyond the noise %.4f; mean %.5f vs %.5f\n",
              error, noise_cycles, noise_ours, beyond, mean_c / cycles1.data.size(), mean_o / ours1.data.size());
  EXPECT_LT(beyond, limit);
  EXPECT_NEAR(mean_c / mean_o, 1.0, 0.03);
}

TEST(BlenderExport, ACyclesRenderOfTheSavedBlendMatchesLightprobesRender) {
  const Fixture f("blender", true);
  const fs::path out = f.root / "blender";
  WriteExport(LoadExportScene(f.scene, f.estimate), ExportFormat::kBlender, out);
  const fs::path blend = f.root / "saved" / "scene.blend";  // elsewhere: the .blend must stand alone
  ASSERT_NO_FATAL_FAILURE(RunBlender("--python '" + (out / "scene.py").string() + "' -- --save '" + blend.string() + "'", f.root / "build.log"));
  ASSERT_TRUE(fs::exists(blend));
  fs::remove(out / "world.exr");
  std::string py = "import bpy; s = bpy.context.scene; s.cycles.samples = " + std::to_string(kCyclesSamples) + "\n";
  for (int seed : {1, 2})
    py += "s.cycles.seed = " + std::to_string(seed) + "; s.render.filepath = '" + (f.root / "cycles").string() +
          std::to_string(seed) + ".exr'; bpy.ops.render.render(write_still=True)\n";
  WriteTextAtomically(f.root / "render.py", py);
  ASSERT_NO_FATAL_FAILURE(
      RunBlender("'" + blend.string() + "' --python '" + (f.root / "render.py").string() + "'", f.root / "render.log"));
  ExpectSamePicture(ReadImageLinear(f.root / "cycles1.exr"), ReadImageLinear(f.root / "cycles2.exr"), f);
}

// A bundle whose up is not +Z (a reconstruction's is gravity's): the export turns it by the
// smallest rotation onto Blender's +Z (docs/formats.md) and the map with it; Cycles' render
// must still be lightprobe's of the bundle as it is. Lit by the map and the lamp (no sun, so
// that the map's orientation shows).
TEST(BlenderExport, ATurnedBundleRendersTheSameInCycles) {
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  const Fixture f("blender_turned", false, turn, false);  // no sun: the map lights more of it
  ASSERT_GT(std::acos(LoadSceneBundle(f.scene).up.dot(Eigen::Vector3d::UnitZ())), 0.3) << "up is not +Z";
  const fs::path out = f.root / "blender";
  WriteExport(LoadExportScene(f.scene, f.estimate), ExportFormat::kBlender, out);
  for (int seed : {1, 2})
    ASSERT_NO_FATAL_FAILURE(RunBlender("--python '" + (out / "scene.py").string() + "' -- --samples " +
                                           std::to_string(kCyclesSamples) + " --seed " + std::to_string(seed) +
                                           " --render '" + (f.root / "cycles").string() + std::to_string(seed) + ".exr'",
                                       f.root / ("render" + std::to_string(seed) + ".log")));
  // Measured 0.0054 beyond the noise; with world.exr written as if up were +Z (the mesh,
  // cameras and lamp turned, the map not) 0.0285, under the 5 %: so 1.5 % here.
  ExpectSamePicture(ReadImageLinear(f.root / "cycles1.exr"), ReadImageLinear(f.root / "cycles2.exr"), f, 0.015);
}

// The route docs/formats.md gives for Blender's own window, Scripting > Open > Run Script:
// there __file__ is the text block's name under the (unsaved) .blend's folder, not the
// script's path; the script finds mesh.ply and world.exr beside its own file all the same
// (run from / here, where a path taken from __file__ finds nothing).
TEST(BlenderExport, RunFromBlendersTextEditorTheScriptFindsItsFiles) {
  const Fixture f("blender_text", false);
  // Two keyframes: a camera each, keyframe 0 the active one with its resolution.
  SceneBundle b = LoadSceneBundle(f.scene);
  View second = b.views[0];
  second.camera.world_from_camera.block<3, 1>(0, 3) += Eigen::Vector3d(0.3, -0.2, 0.1);
  b.views.push_back(second);
  WriteSceneBundle(f.scene, b);
  const Eigen::Vector3d c1 = second.camera.center();  // up is +Z: Blender's frame is the bundle's
  const fs::path out = f.root / "blender";
  WriteExport(LoadExportScene(f.scene, f.estimate), ExportFormat::kBlender, out);
  WriteTextAtomically(f.root / "run_text.py",
                      "import bpy\n"
                      "t = bpy.data.texts.load('" + (out / "scene.py").string() + "')\n"
                      "with bpy.context.temp_override(edit_text=t):\n"
                      "    bpy.ops.text.run_script()\n"
                      "print('OBJECTS', ' '.join(sorted(o.name for o in bpy.data.objects)))\n"
                      "print('WORLD', bpy.context.scene.world.node_tree.nodes['Environment Texture'].image.name)\n"
                      "s = bpy.context.scene\n"
                      "print('ACTIVE %s %dx%d' % (s.camera.name, s.render.resolution_x, s.render.resolution_y))\n"
                      "print('KEYFRAME1 %.4f %.4f %.4f' % tuple(bpy.data.objects['keyframe_1'].location))\n");
  ASSERT_NO_FATAL_FAILURE(RunBlender("--python '" + (f.root / "run_text.py").string() + "'", f.root / "text.log", "/"));
  std::ifstream in(f.root / "text.log");
  std::stringstream log;
  log << in.rdbuf();
  EXPECT_NE(log.str().find("OBJECTS keyframe_0 keyframe_1 lightprobe_mesh point_light_0"), std::string::npos) << log.str();
  EXPECT_NE(log.str().find("WORLD world.exr"), std::string::npos) << log.str();
  EXPECT_NE(log.str().find("ACTIVE keyframe_0 80x60"), std::string::npos) << log.str();
  char where[120];
  std::snprintf(where, sizeof where, "KEYFRAME1 %.4f %.4f %.4f", c1.x(), c1.y(), c1.z());
  EXPECT_NE(log.str().find(where), std::string::npos) << where << "\n" << log.str();
}

TEST(GltfExport, ACyclesRenderThroughBlendersGltfImporterMatchesLightprobesRender) {
  const Fixture f("gltf", false);
  const fs::path out = f.root / "gltf";
  WriteExport(LoadExportScene(f.scene, f.estimate), ExportFormat::kGltf, out);
  ASSERT_NO_FATAL_FAILURE(RunBlender("--python '" + (fs::path(LIGHTPROBE_SOURCE_DIR) / "tests/exports/render_gltf.py").string() + "' -- '" +
                 out.string() + "' '" + (f.root / "cycles").string() + "' " + std::to_string(kCyclesSamples) + " 1 2",
                                     f.root / "render.log"));
  ExpectSamePicture(ReadImageLinear(f.root / "cycles1.exr"), ReadImageLinear(f.root / "cycles2.exr"), f);
}

/// The pane of the Cycles window scenes (their truth.json; make-cycles-sun.py's PANES["glow"]):
/// x = 0, y 1.2-2.0, z 0.5-1.3, facing +x (into the room).
std::shared_ptr<const EmitterShape> ThePane() {
  Mesh quad;
  quad.positions = {{0, 1.2f, 0.5f}, {0, 2.0f, 0.5f}, {0, 2.0f, 1.3f}, {0, 1.2f, 1.3f}};
  quad.albedo.assign(4, Eigen::Vector3f::Zero());
  quad.triangles = {{0, 1, 2}, {0, 2, 3}};
  return MakeEmitterShape(quad, {0, 1}, {Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitX()});
}

/// The Cycles frosted window (tests/data/cycles/glow: its view rendered by Cycles from the
/// original scene, a pane of radiance (3, 2.7, 2.25) in a wall, no other light) with the
/// true pane as an estimate's only light, written into `estimate`.
fs::path TruePaneEstimate(const fs::path& estimate) {
  fs::create_directories(estimate);
  EmitterLight pane;
  pane.shape = ThePane();
  pane.radiance = {3.0, 2.7, 2.25};
  const std::vector<Light> lights{pane};
  WriteEmittersPly(estimate / "emitters.ply", lights);
  WriteTextAtomically(estimate / "lights.json", LightsJson({"", lights, {}, {}}));
  return fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data" / "cycles" / "glow";
}

/// A Cycles render of the export against the original scene's view 0 (as Cycles rendered it).
/// The picture averaged over each pixel's 3 x 3 neighbourhood (within the image).
ImageRGB Blur3(const ImageRGB& in) {
  ImageRGB out(in.width, in.height);
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      double sum[3] = {0, 0, 0};
      int n = 0;
      for (int v = std::max(0, y - 1); v <= std::min(in.height - 1, y + 1); ++v)
        for (int u = std::max(0, x - 1); u <= std::min(in.width - 1, x + 1); ++u, ++n)
          for (int c = 0; c < 3; ++c) sum[c] += in.at(u, v)[c];
      for (int c = 0; c < 3; ++c) out.at(x, y)[c] = static_cast<float>(sum[c] / n);
    }
  return out;
}

/// `blur`: both pictures compared after Blur3, where the scene's silhouettes stand against
/// a bright world: the bundle's camera and mesh, written from Cycles' scene, put an edge a
/// fraction of a pixel off, which shows as whole edge pixels of the world's radiance.
void ExpectTheOriginalPicture(const ImageRGB& export_render, const fs::path& original_scene, bool blur = false) {
  const ImageRGB original = blur ? Blur3(LoadSceneBundle(original_scene).views[0].image)
                                 : LoadSceneBundle(original_scene).views[0].image;
  const ImageRGB ours = blur ? Blur3(export_render) : export_render;
  ASSERT_EQ(ours.width, original.width);
  const double error = Rmse(ours, original);
  double mean_o = 0, mean_e = 0;
  for (std::size_t i = 0; i < ours.data.size(); ++i) mean_e += ours.data[i], mean_o += original.data[i];
  std::printf("the export's Cycles render against the original's: relative RMSE %.4f, mean %.5f vs %.5f\n", error,
              mean_e / ours.data.size(), mean_o / ours.data.size());
  EXPECT_LT(error, 0.08);
  EXPECT_NEAR(mean_e / mean_o, 1.0, 0.03);
}

/// Cycles' render (256 samples) of keyframe 0 of `scene` exported in `format` under `root`:
/// the Blender export's scene.py, or the glTF export through Blender's glTF importer.
ImageRGB CyclesRenderOfTheExport(const ExportScene& scene, ExportFormat format, const fs::path& root) {
  const fs::path out = root / ToString(format);
  WriteExport(scene, format, out);
  const std::string args =
      format == ExportFormat::kBlender
          ? "--python '" + (out / "scene.py").string() + "' -- --samples 256 --render '" + (root / "cycles1.exr").string() + "'"
          : "--python '" + (fs::path(LIGHTPROBE_SOURCE_DIR) / "tests/exports/render_gltf.py").string() + "' -- '" +
                out.string() + "' '" + (root / "cycles").string() + "' 256 1";
  RunBlender(args, root / "render.log");
  return ReadImageLinear(root / "cycles1.exr");
}

/// Writes the estimate `make` makes (returning its original scene), exports it in `format`
/// and expects Cycles' render of the export to be the original scene's view 0.
void ExpectTheExportRendersTheOriginal(const std::string& name, fs::path (*make)(const fs::path&), ExportFormat format,
                                       bool blur = false) {
  const fs::path root = Scratch(name), estimate = root / "estimate";
  const fs::path original = make(estimate);
  ImageRGB render;
  ASSERT_NO_FATAL_FAILURE(render = CyclesRenderOfTheExport(LoadExportScene(original, estimate), format, root));
  ExpectTheOriginalPicture(render, original, blur);
  fs::remove_all(root);
}

// Issue 43: a glowing surface in the Blender export. With the true pane as the estimate's
// emitter, scene.py must build a scene whose Cycles render is the original's (the emitter
// just off the wall, glowing on its side, the wall's own reflection showing through it).
TEST(BlenderExport, AGlowingSurfaceRendersAsTheOriginalCyclesScene) {
  ExpectTheExportRendersTheOriginal("glow", TruePaneEstimate, ExportFormat::kBlender);
}

// The same through glTF: the wall's faces on the pane get the emissive material (the pane's
// radiance in nits), and Blender's glTF importer builds the original scene from it.
TEST(GltfExport, AGlowingSurfaceRendersAsTheOriginalCyclesScene) {
  ExpectTheExportRendersTheOriginal("glow_gltf", TruePaneEstimate, ExportFormat::kGltf);
}

/// The Cycles glazed window (tests/data/cycles/glazed_window: the room rendered with nothing
/// in the window's hole, the world bright (radiance 4) only in a cone of 37 degrees about -x;
/// the bundle's mesh has a pane in the hole) with its true world as an estimate's map and the
/// pane as its opening, written into `estimate`.
fs::path TrueOpeningEstimate(const fs::path& estimate) {
  fs::create_directories(estimate);
  const fs::path glazed = fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data" / "cycles" / "glazed_window";
  const EnvMap frame(13, LoadSceneBundle(glazed).up);  // (only its frame: the picture is the world itself)
  ImageRGB world(1024, 512);
  for (int y = 0; y < world.height; ++y)
    for (int x = 0; x < world.width; ++x) {
      const double theta = (y + 0.5) / world.height * M_PI, phi = (x + 0.5) / world.width * 2 * M_PI;
      const float radiance = frame.FromSpherical(theta, phi).x() < -0.8 ? 4.f : 0.f;
      for (int c = 0; c < 3; ++c) world.at(x, y)[c] = radiance;
    }
  WriteExr(estimate / "envmap.exr", world);
  const std::vector<std::shared_ptr<const EmitterShape>> openings{ThePane()};
  WriteOpeningsPly(estimate / "openings.ply", openings);
  WriteTextAtomically(estimate / "lights.json", LightsJson({"envmap.exr", {}, {}, openings}));
  return glazed;
}

// Issue 43: a window's opening in the exports. With the glazed window's true world as the map
// and its pane as the estimate's opening, the export leaves the pane's triangles out of the
// mesh, so Blender's world shines through the hole as Cycles' original did: the beam on the
// floor and the world seen through the window. Measured: relative RMSE 0.038 (3 x 3 blurred),
// the means within 0.1 %; with the pane left in the mesh, 1.17 and the mean 21 % low.
TEST(BlenderExport, AWindowsOpeningRendersAsTheOriginalCyclesScene) {
  const fs::path root = Scratch("opening_load"), estimate = root / "estimate";
  const fs::path glazed = TrueOpeningEstimate(estimate);
  const ExportScene scene = LoadExportScene(glazed, estimate);
  EXPECT_EQ(scene.openings, 1u);
  EXPECT_EQ(scene.opening_triangles, 2u);
  EXPECT_EQ(scene.mesh.triangles.size(), LoadSceneBundle(glazed).mesh.triangles.size() - 2);
  fs::remove_all(root);
  ExpectTheExportRendersTheOriginal("opening", TrueOpeningEstimate, ExportFormat::kBlender, true);
}

// The same through glTF: the mesh without the pane, environment.hdr as Blender's world.
TEST(GltfExport, AWindowsOpeningRendersAsTheOriginalCyclesScene) {
  ExpectTheExportRendersTheOriginal("opening_gltf", TrueOpeningEstimate, ExportFormat::kGltf, true);
}

}  // namespace
}  // namespace lp
