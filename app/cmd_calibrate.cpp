// `lightprobe calibrate geometry | response | vignetting`: fits one part of the colour
// camera's calibration and writes it into a calibration file (creating it, or updating
// that part of an existing one).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>

#include "app/commands.h"
#include "calibration/calibration.h"
#include "calibration/geometry.h"
#include "capture/frame_source.h"
#include "capture/openni.h"
#include "reconstruction/keyframe_vignetting.h"
#include "common/color.h"
#include "common/image_io.h"

namespace lp::app {
namespace fs = std::filesystem;

namespace {

Calibration LoadOrNew(const std::string& path) {
  std::error_code ec;
  return fs::exists(path, ec) ? ReadCalibration(path) : Calibration{};
}

std::vector<ImageRgb8> ReadImages(const std::vector<std::string>& paths) {
  std::vector<ImageRgb8> images;
  for (const std::string& p : paths) images.push_back(ReadRgb8(p));
  return images;
}

/// "COLSxROWS" into the board's inner corners.
void ParseBoard(const std::string& board, const char* command, CheckerboardOptions* o) {
  if (std::sscanf(board.c_str(), "%dx%d", &o->inner_columns, &o->inner_rows) != 2)
    throw InputError(std::string(command) + ": --board must be COLSxROWS, e.g. 9x6");
}

void Save(const std::string& out, const Calibration& c) {
  WriteCalibration(out, c);
  std::printf("wrote %s (%s)\n", fs::absolute(out).lexically_normal().c_str(), c.Describe().c_str());
}

/// One subcommand of calibrate: its command line, and what it fits into the calibration
/// (printing what it found).
struct Part {
  CLI::App* command;
  std::function<void(Calibration*)> fit;
};

// ---- calibrate geometry ----

struct GeometryArgs {
  std::vector<std::string> images;
  std::string board = "9x6";
  CheckerboardOptions board_options;
  bool no_distortion = false;
};

void RunGeometry(const GeometryArgs& a, Calibration* c) {
  CheckerboardOptions board = a.board_options;
  ParseBoard(a.board, "calibrate geometry", &board);
  board.distortion = !a.no_distortion;
  const GeometryFit fit = CalibrateGeometry(ReadImages(a.images), board);
  const CameraModel& m = fit.camera;
  std::printf("board found in %d of %zu images; reprojection error %.3f px RMS\n", fit.images_used, a.images.size(),
              fit.rms_reprojection);
  std::printf("fx %.2f fy %.2f cx %.2f cy %.2f, distortion %.4f %.4f %.4f %.4f %.4f\n", m.fx, m.fy, m.cx, m.cy,
              m.distortion[0], m.distortion[1], m.distortion[2], m.distortion[3], m.distortion[4]);
  c->color = m;
}

Part AddGeometry(CLI::App& cmd, std::string* out) {
  auto* geo = cmd.add_subcommand("geometry", "intrinsics and distortion from checkerboard images (OpenCV)");
  auto a = std::make_shared<GeometryArgs>();
  geo->add_option("IMAGES", a->images, "checkerboard images (PNG/JPEG), one size")->required();
  geo->add_option("--board", a->board, "inner corners COLSxROWS")->capture_default_str();
  geo->add_option("--square", a->board_options.square, "square size in metres")->capture_default_str();
  geo->add_flag("--no-distortion", a->no_distortion, "fit a pinhole only (no k1 k2 p1 p2 k3)");
  geo->add_option("--out", *out, "calibration file to write or update")->required();
  return {geo, [a](Calibration* c) { RunGeometry(*a, c); }};
}

// ---- calibrate response ----

struct ResponseArgs {
  std::vector<std::string> images;
  std::vector<double> exposures;
  std::string device;
  bool use_device = false;
  std::string size = "640x480";
  int gain = -1;
  bool keep_ratios = false;
};

/// The bracket from a live camera, one frame per exposure.
std::vector<ImageRgb8> CaptureImages(const ResponseArgs& a) {
  if (!a.images.empty()) throw InputError("calibrate response: give IMAGES or --device, not both");
  OpenNiDeviceOptions o;
  o.uri = a.device;
  if (std::sscanf(a.size.c_str(), "%dx%d", &o.width, &o.height) != 2)
    throw InputError("calibrate response: --size must be WxH");
  o.gain = a.gain;
  std::vector<int> ex;
  for (double v : a.exposures) ex.push_back(static_cast<int>(std::lround(v)));
  std::vector<ImageRgb8> images;
  for (const RgbdFrame& f : CaptureBracket(o, ex)) {
    images.push_back(f.color);
    std::printf("captured exposure %.0f, gain %.0f\n", f.exposure, f.gain);
  }
  return images;
}

void PrintResponseFit(const ResponseFit& fit) {
  double srgb = 0;
  for (int v = 6; v <= 249; ++v)
    for (int ch = 0; ch < 3; ++ch) srgb += std::pow(fit.response.Apply(ch, v / 255.0) - SrgbToLinear(v / 255.f), 2);
  std::printf("inverse response: degrees %d/%d/%d, fit residual %.4f/%.4f/%.4f; differs from sRGB by %.2f %% RMS\n",
              fit.degree[0], fit.degree[1], fit.degree[2], fit.rms[0], fit.rms[1], fit.rms[2],
              100 * std::sqrt(srgb / (3 * 244)));
  if (std::max({fit.rms[0], fit.rms[1], fit.rms[2]}) > 0.01)
    std::printf("warning: the fit residual is large: was the scene static, the camera still and the exposure "
                "locked for every image?\n");
  std::printf("exposures relative to the first:");
  for (double x : fit.exposures) std::printf(" %.4f", x);
  std::printf("\n");
}

void RunResponse(const ResponseArgs& a, Calibration* c) {
  const std::vector<ImageRgb8> images = a.use_device ? CaptureImages(a) : ReadImages(a.images);
  ResponseFitOptions ro;
  ro.refine_ratios = !a.keep_ratios;
  const ResponseFit fit = FitResponse(images, a.exposures, ro);
  PrintResponseFit(fit);
  c->response = fit.response;
}

Part AddResponse(CLI::App& cmd, std::string* out) {
  auto* resp = cmd.add_subcommand("response", "inverse response from an exposure bracket (Mitsunaga-Nayar)");
  auto a = std::make_shared<ResponseArgs>();
  resp->add_option("IMAGES", a->images, "bracket images of one static scene (PNG/JPEG), or use --device");
  resp->add_option("--exposures", a->exposures, "exposure x gain of each image (or device exposures with --device)")
      ->required();
  resp->add_flag("--device", a->use_device, "capture the bracket from a live camera through OpenNI2 (manual exposure)");
  resp->add_option("--source", a->device, "with --device: OpenNI2 URI (default: the first camera)");
  resp->add_option("--size", a->size, "with --device: stream size WxH")->capture_default_str();
  resp->add_option("--gain", a->gain, "with --device: colour gain to hold (default: as the camera has it)");
  resp->add_flag("--keep-ratios", a->keep_ratios, "trust the exposures as given (default: refine their ratios)");
  resp->add_option("--out", *out, "calibration file to write or update")->required();
  return {resp, [a](Calibration* c) { RunResponse(*a, c); }};
}

// ---- calibrate vignetting ----

struct VignettingArgs {
  std::vector<std::string> images;
  std::string scene;
};

/// From the keyframes of a reconstruction: the same surface points seen at different radii.
Vignetting FitKeyframeVignetting(const std::string& scene) {
  // Keyframes already divided by a vignetting model would measure only what is left.
  const fs::path applied = fs::path(scene) / "calibration.json";
  if (fs::exists(applied) && !ReadCalibration(applied).vignetting.identity())
    throw InputError(applied.string(), "the keyframes were already corrected for vignetting: reconstruct with "
                                       "a calibration without it (or none) to measure it");
  const std::vector<VignettingPair> pairs = KeyframeVignettingPairs(LoadSceneBundle(scene));
  std::printf("%zu pairs of sightings of the same surface points\n", pairs.size());
  return FitVignettingPairs(pairs);
}

/// From flat-field images, linearized by the calibration's response only.
Vignetting FitFlatFieldVignetting(const std::vector<std::string>& images, const Calibration& c) {
  std::vector<ImageRGB> flats;
  Calibration linear = c;  // the response only: vignetting is what is measured
  linear.vignetting = Vignetting{};
  linear.color.reset();
  linear.reference_exposure = 0;
  for (const ImageRgb8& im : ReadImages(images)) flats.push_back(Linearize(im, linear));
  return FitVignettingFlatField(flats);
}

void RunVignetting(const VignettingArgs& a, Calibration* c) {
  if (a.images.empty() == a.scene.empty())
    throw InputError("calibrate vignetting: give flat-field IMAGES or --scene SCENE_DIR");
  c->vignetting = !a.scene.empty() ? FitKeyframeVignetting(a.scene) : FitFlatFieldVignetting(a.images, *c);
  const Vignetting& v = c->vignetting;
  std::printf("vignetting V(r) = 1 %+.4f r^2 %+.4f r^4 %+.4f r^6 (corners at %.1f %% of the centre)\n", v.a, v.b,
              v.c, 100 * (1 + v.a + v.b + v.c));
}

Part AddVignetting(CLI::App& cmd, std::string* out) {
  auto* vig = cmd.add_subcommand("vignetting", "vignetting from flat-field images or a reconstruction's keyframes");
  auto a = std::make_shared<VignettingArgs>();
  vig->add_option("IMAGES", a->images, "flat-field images (PNG/JPEG) of a uniformly lit flat target");
  vig->add_option("--scene", a->scene,
                  "instead: a scene bundle (lightprobe reconstruct, no vignetting applied): the same surface points "
                  "seen at different radii in its keyframes");
  vig->add_option("--out", *out, "calibration file to write or update (its response linearizes the images)")
      ->required();
  return {vig, [a](Calibration* c) { RunVignetting(*a, c); }};
}

// ---- calibrate extrinsics ----

struct ExtrinsicsArgs {
  std::string source;
  int every = 10;
  std::string board = "9x6";
  CheckerboardOptions board_options;
};

/// One frame's colour image and depth (metres) with the depth camera's intrinsics.
DepthColorView ToDepthColorView(const RgbdFrame& f) {
  DepthColorView v;
  v.color = f.color;
  v.depth_width = f.depth.width;
  v.depth_height = f.depth.height;
  v.depth.resize(f.depth.data.size());
  for (std::size_t p = 0; p < v.depth.size(); ++p) v.depth[p] = f.depth.data[p] * 1e-3f;
  v.dfx = f.depth_intrinsics.fx;
  v.dfy = f.depth_intrinsics.fy;
  v.dcx = f.depth_intrinsics.cx;
  v.dcy = f.depth_intrinsics.cy;
  return v;
}

void RunExtrinsics(const ExtrinsicsArgs& a, Calibration* c) {
  CheckerboardOptions board = a.board_options;
  ParseBoard(a.board, "calibrate extrinsics", &board);
  auto src = OpenFrameSource(a.source);
  std::vector<DepthColorView> views;
  std::optional<CameraModel> camera = c->color;  // else the first frame's colour intrinsics
  RgbdFrame f;
  for (int k = 0; src->Next(&f, 5.0) == SourceStatus::kFrame; ++k) {
    if (k % std::max(1, a.every) != 0) continue;
    if (!camera) camera = CameraModel{f.color_intrinsics, {}};
    views.push_back(ToDepthColorView(f));
  }
  if (!camera) throw InputError(a.source, "has no frames");
  const ExtrinsicsFit fit = CalibrateDepthToColor(views, *camera, board);
  const Eigen::Matrix4d& T = fit.color_from_depth;
  std::printf("%d views used; boards' depth points to their planes %.2f mm RMS; colour from depth: translation "
              "(%.4f, %.4f, %.4f) m\n",
              fit.views_used, 1e3 * fit.plane_rms, T(0, 3), T(1, 3), T(2, 3));
  c->color_from_depth = T;
}

Part AddExtrinsics(CLI::App& cmd, std::string* out) {
  auto* ext = cmd.add_subcommand("extrinsics", "depth-to-colour extrinsics from RGB-D frames of a checkerboard");
  auto a = std::make_shared<ExtrinsicsArgs>();
  ext->add_option("SOURCE", a->source, ".oni recording or frame directory of a board tilted in several directions "
                                       "(depth not registered to colour)")
      ->required();
  ext->add_option("--every", a->every, "use every Nth frame")->capture_default_str();
  ext->add_option("--board", a->board, "inner corners COLSxROWS")->capture_default_str();
  ext->add_option("--square", a->board_options.square, "square size in metres")->capture_default_str();
  ext->add_option("--out", *out, "calibration file to write or update (its camera model is used when present)")
      ->required();
  return {ext, [a](Calibration* c) { RunExtrinsics(*a, c); }};
}

}  // namespace

Run AddCalibrate(CLI::App& app) {
  auto* cmd = app.add_subcommand("calibrate", "calibrate the colour camera (geometry, response, vignetting)");
  cmd->require_subcommand(1);
  auto out = std::make_shared<std::string>();  // every subcommand's --out
  const std::vector<Part> parts = {AddGeometry(*cmd, out.get()), AddResponse(*cmd, out.get()),
                                   AddVignetting(*cmd, out.get()), AddExtrinsics(*cmd, out.get())};
  return [out, parts] {  // exactly one subcommand runs
    Calibration c = LoadOrNew(*out);
    for (const Part& part : parts)
      if (part.command->parsed()) {
        part.fit(&c);
        Save(*out, c);
        break;
      }
  };
}

}  // namespace lp::app
