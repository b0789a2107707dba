// `lightprobe calibrate geometry | response | vignetting`: fits one part of the colour
// camera's calibration and writes it into a calibration file (creating it, or updating
// that part of an existing one).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
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

}  // namespace

Run AddCalibrate(CLI::App& app) {
  auto* cmd = app.add_subcommand("calibrate", "calibrate the colour camera (geometry, response, vignetting)");
  cmd->require_subcommand(1);
  auto out = std::make_shared<std::string>();

  auto* geo = cmd->add_subcommand("geometry", "intrinsics and distortion from checkerboard images (OpenCV)");
  auto geo_images = std::make_shared<std::vector<std::string>>();
  auto board = std::make_shared<std::string>("9x6");
  auto go = std::make_shared<CheckerboardOptions>();
  auto no_distortion = std::make_shared<bool>(false);
  geo->add_option("IMAGES", *geo_images, "checkerboard images (PNG/JPEG), one size")->required();
  geo->add_option("--board", *board, "inner corners COLSxROWS")->capture_default_str();
  geo->add_option("--square", go->square, "square size in metres")->capture_default_str();
  geo->add_flag("--no-distortion", *no_distortion, "fit a pinhole only (no k1 k2 p1 p2 k3)");
  geo->add_option("--out", *out, "calibration file to write or update")->required();

  auto* resp = cmd->add_subcommand("response", "inverse response from an exposure bracket (Mitsunaga-Nayar)");
  auto resp_images = std::make_shared<std::vector<std::string>>();
  auto exposures = std::make_shared<std::vector<double>>();
  auto device = std::make_shared<std::string>();
  auto use_device = std::make_shared<bool>(false);
  auto size = std::make_shared<std::string>("640x480");
  auto gain = std::make_shared<int>(-1);
  auto keep_ratios = std::make_shared<bool>(false);
  resp->add_option("IMAGES", *resp_images, "bracket images of one static scene (PNG/JPEG), or use --device");
  resp->add_option("--exposures", *exposures, "exposure x gain of each image (or device exposures with --device)")
      ->required();
  resp->add_flag("--device", *use_device, "capture the bracket from a live camera through OpenNI2 (manual exposure)");
  resp->add_option("--source", *device, "with --device: OpenNI2 URI (default: the first camera)");
  resp->add_option("--size", *size, "with --device: stream size WxH")->capture_default_str();
  resp->add_option("--gain", *gain, "with --device: colour gain to hold (default: as the camera has it)");
  resp->add_flag("--keep-ratios", *keep_ratios, "trust the exposures as given (default: refine their ratios)");
  resp->add_option("--out", *out, "calibration file to write or update")->required();

  auto* vig = cmd->add_subcommand("vignetting", "vignetting from flat-field images or a reconstruction's keyframes");
  auto vig_images = std::make_shared<std::vector<std::string>>();
  auto scene = std::make_shared<std::string>();
  vig->add_option("IMAGES", *vig_images, "flat-field images (PNG/JPEG) of a uniformly lit flat target");
  vig->add_option("--scene", *scene,
                  "instead: a scene bundle (lightprobe reconstruct, no vignetting applied): the same surface points "
                  "seen at different radii in its keyframes");
  vig->add_option("--out", *out, "calibration file to write or update (its response linearizes the images)")
      ->required();

  auto* ext = cmd->add_subcommand("extrinsics", "depth-to-colour extrinsics from RGB-D frames of a checkerboard");
  auto ext_source = std::make_shared<std::string>();
  auto every = std::make_shared<int>(10);
  auto ext_board = std::make_shared<std::string>("9x6");
  auto eo = std::make_shared<CheckerboardOptions>();
  ext->add_option("SOURCE", *ext_source, ".oni recording or frame directory of a board tilted in several directions "
                                         "(depth not registered to colour)")
      ->required();
  ext->add_option("--every", *every, "use every Nth frame")->capture_default_str();
  ext->add_option("--board", *ext_board, "inner corners COLSxROWS")->capture_default_str();
  ext->add_option("--square", eo->square, "square size in metres")->capture_default_str();
  ext->add_option("--out", *out, "calibration file to write or update (its camera model is used when present)")
      ->required();

  return [=] {
    Calibration c = LoadOrNew(*out);
    if (geo->parsed()) {
      ParseBoard(*board, "calibrate geometry", go.get());
      go->distortion = !*no_distortion;
      const GeometryFit fit = CalibrateGeometry(ReadImages(*geo_images), *go);
      const CameraModel& m = fit.camera;
      std::printf("board found in %d of %zu images; reprojection error %.3f px RMS\n", fit.images_used,
                  geo_images->size(), fit.rms_reprojection);
      std::printf("fx %.2f fy %.2f cx %.2f cy %.2f, distortion %.4f %.4f %.4f %.4f %.4f\n", m.fx, m.fy, m.cx, m.cy,
                  m.distortion[0], m.distortion[1], m.distortion[2], m.distortion[3], m.distortion[4]);
      c.color = m;
      Save(*out, c);
    } else if (resp->parsed()) {
      std::vector<ImageRgb8> images;
      std::vector<double> e = *exposures;
      if (*use_device) {
        if (!resp_images->empty()) throw InputError("calibrate response: give IMAGES or --device, not both");
        OpenNiDeviceOptions o;
        o.uri = *device;
        if (std::sscanf(size->c_str(), "%dx%d", &o.width, &o.height) != 2)
          throw InputError("calibrate response: --size must be WxH");
        o.gain = *gain;
        std::vector<int> ex;
        for (double v : e) ex.push_back(static_cast<int>(std::lround(v)));
        for (const RgbdFrame& f : CaptureBracket(o, ex)) {
          images.push_back(f.color);
          std::printf("captured exposure %.0f, gain %.0f\n", f.exposure, f.gain);
        }
      } else {
        images = ReadImages(*resp_images);
      }
      ResponseFitOptions ro;
      ro.refine_ratios = !*keep_ratios;
      const ResponseFit fit = FitResponse(images, e, ro);
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
      c.response = fit.response;
      Save(*out, c);
    } else if (ext->parsed()) {
      ParseBoard(*ext_board, "calibrate extrinsics", eo.get());
      auto src = OpenFrameSource(*ext_source);
      std::vector<DepthColorView> views;
      std::optional<CameraModel> camera = c.color;
      RgbdFrame f;
      for (int k = 0; src->Next(&f, 5.0) == SourceStatus::kFrame; ++k) {
        if (k % std::max(1, *every) != 0) continue;
        if (!camera) {
          const Intrinsics& i = f.color_intrinsics;
          camera = CameraModel{i.width, i.height, i.fx, i.fy, i.cx, i.cy, {}};
        }
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
        views.push_back(std::move(v));
      }
      if (!camera) throw InputError(*ext_source, "has no frames");
      const ExtrinsicsFit fit = CalibrateDepthToColor(views, *camera, *eo);
      const Eigen::Matrix4d& T = fit.color_from_depth;
      std::printf("%d views used; boards' depth points to their planes %.2f mm RMS; colour from depth: translation "
                  "(%.4f, %.4f, %.4f) m\n",
                  fit.views_used, 1e3 * fit.plane_rms, T(0, 3), T(1, 3), T(2, 3));
      c.color_from_depth = T;
      Save(*out, c);
    } else if (vig->parsed()) {
      if (vig_images->empty() == scene->empty())
        throw InputError("calibrate vignetting: give flat-field IMAGES or --scene SCENE_DIR");
      if (!scene->empty()) {
        // Keyframes already divided by a vignetting model would measure only what is left.
        const fs::path applied = fs::path(*scene) / "calibration.json";
        if (fs::exists(applied) && !ReadCalibration(applied).vignetting.identity())
          throw InputError(applied.string(), "the keyframes were already corrected for vignetting: reconstruct with "
                                             "a calibration without it (or none) to measure it");
        const std::vector<VignettingPair> pairs = KeyframeVignettingPairs(LoadSceneBundle(*scene));
        std::printf("%zu pairs of sightings of the same surface points\n", pairs.size());
        c.vignetting = FitVignettingPairs(pairs);
      } else {
        std::vector<ImageRGB> flats;
        Calibration linear = c;  // the response only: vignetting is what is measured
        linear.vignetting = Vignetting{};
        linear.color.reset();
        linear.reference_exposure = 0;
        for (const ImageRgb8& im : ReadImages(*vig_images)) flats.push_back(Linearize(im, linear));
        c.vignetting = FitVignettingFlatField(flats);
      }
      const Vignetting& v = c.vignetting;
      std::printf("vignetting V(r) = 1 %+.4f r^2 %+.4f r^4 %+.4f r^6 (corners at %.1f %% of the centre)\n", v.a, v.b,
                  v.c, 100 * (1 + v.a + v.b + v.c));
      Save(*out, c);
    }
  };
}

}  // namespace lp::app
