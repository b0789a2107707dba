#include "app/scan_evaluation.h"

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/color.h"
#include "common/error.h"
#include "common/image_io.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "estimation/envmap.h"
#include "estimation/light_render.h"
#include "estimation/lights_file.h"
#include "estimation/path_tracer.h"
#include "estimation/sampling.h"
#include "estimation/truth.h"
#include "reconstruction/geometry.h"
#include "scene/ray_tracer.h"

namespace lp::app {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// `file`'s JSON (its `text` when already read).
json ReadJsonFile(const fs::path& file, const std::string& text = {}) {
  try {
    return json::parse(text.empty() ? ReadTextFile(file) : text);
  } catch (const json::exception& e) {
    throw InputError(file.string(), std::string("malformed JSON: ") + e.what());
  }
}

double Number(const json& j, const char* key, const fs::path& file) {
  if (!j.contains(key) || !j[key].is_number()) throw InputError(file.string(), std::string("no number \"") + key + "\"");
  return j[key].get<double>();
}

Eigen::Vector3d Vec3(const json& j, const char* key, const fs::path& file) {
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3)
    throw InputError(file.string(), std::string("\"") + key + "\" must be 3 numbers");
  return {j[key][0].get<double>(), j[key][1].get<double>(), j[key][2].get<double>()};
}

double Percentile(std::vector<float> v, double q) {
  if (v.empty()) return NAN;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

/// Points on `mesh`'s triangles about every `spacing` metres (each triangle's barycentric
/// grid), for distances to a surface rather than to its vertices.
std::vector<Eigen::Vector3f> SurfacePoints(const Mesh& mesh, double spacing) {
  std::vector<Eigen::Vector3f> out;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3f a = mesh.positions[t[0]], b = mesh.positions[t[1]], c = mesh.positions[t[2]];
    const double edge = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    const int n = std::max(1, static_cast<int>(std::ceil(edge / spacing)));
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const float u = static_cast<float>(i) / n, v = static_cast<float>(j) / n;
        out.push_back(a + u * (b - a) + v * (c - a));
      }
  }
  return out;
}

/// The true lamps (point lights with a position and an intensity in image units) and the
/// room's centre of truth.json.
struct TrueLamps {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<PointLight> lamps;
  std::vector<DirectionalLight> suns;  ///< irradiance from "irradiance_rgb_W_per_m2"
  std::vector<EmitterLight> emitters;  ///< "emitters" (ParseTruthEmitters)
};

TrueLamps ReadTrueLamps(const fs::path& file) {
  const std::string text = ReadTextFile(file);
  const json j = ReadJsonFile(file, text);
  TrueLamps t;
  t.emitters = ParseTruthEmitters(text, file.string());
  if (j.contains("scene_bbox") && j["scene_bbox"].contains("centre")) t.centre = Vec3(j["scene_bbox"], "centre", file);
  if (!j.contains("lights") || !j["lights"].is_array()) return t;
  for (const json& l : j["lights"]) {
    if (!l.contains("position") && l.contains("direction") && l.contains("irradiance_rgb_W_per_m2")) {
      DirectionalLight d;
      d.direction = Vec3(l, "direction", file).normalized();
      d.irradiance = Vec3(l, "irradiance_rgb_W_per_m2", file);
      t.suns.push_back(d);
      continue;
    }
    if (!l.contains("position") || !l.contains("intensity_image_units")) continue;
    PointLight p;
    p.position = Vec3(l, "position", file);
    p.intensity = Vec3(l, "intensity_image_units", file);
    if (l.contains("radius") && l["radius"].is_number()) p.radius = l["radius"].get<double>();
    t.lamps.push_back(p);
  }
  return t;
}

double Lum(const Eigen::Vector3d& v) { return Luminance(v.x(), v.y(), v.z()); }

/// Each true lamp against its nearest estimate; the estimates no lamp has as its nearest
/// are spurious (their share of the estimated lamps' irradiance at the centre).
void ScoreLamps(const TrueLamps& truth, const std::vector<PointLight>& estimate, ScanScore* s) {
  std::vector<bool> matched(estimate.size(), false);
  for (const PointLight& t : truth.lamps) {
    LampScore ls;
    ls.truth = t.position;
    ls.distance_m = (t.position - truth.centre).norm();
    int best = -1;
    for (std::size_t k = 0; k < estimate.size(); ++k)
      if (best < 0 || (estimate[k].position - t.position).norm() < (estimate[best].position - t.position).norm())
        best = static_cast<int>(k);
    if (best >= 0) {
      matched[best] = true;
      ls.estimate = estimate[best].position;
      ls.error_m = (ls.estimate - t.position).norm();
      ls.share = ls.error_m / ls.distance_m;
      ls.intensity_ratio = Lum(estimate[best].intensity) / Lum(t.intensity);
    }
    s->lamps.push_back(ls);
  }
  double total = 0;
  std::vector<double> at_centre;
  for (const PointLight& e : estimate) {
    at_centre.push_back(Lum(e.intensity) / std::max(1e-6, (e.position - truth.centre).squaredNorm()));
    total += at_centre.back();
  }
  for (std::size_t k = 0; k < estimate.size(); ++k)
    if (!matched[k] && total > 0) s->spurious_share = std::max(s->spurious_share, at_centre[k] / total);
  s->estimated_lamps = static_cast<int>(estimate.size());
}

/// An estimated emitter's point counts as on a true one within this of its surface (issue
/// 43's measure: "within 2 cm of the true emitter's surface").
constexpr double kOnTrueEmitter = 0.02;  // m

/// Each true emitter against the estimate overlapping it most; the estimates overlapping
/// none are spurious (their share of the estimated emitters' power).
void ScoreEmitters(const std::vector<EmitterLight>& truth, const std::vector<EmitterLight>& estimate, ScanScore* s) {
  std::vector<bool> matched(estimate.size(), false);
  for (const EmitterLight& t : truth) {
    EmitterScore es;
    es.true_area = t.Area();
    for (std::size_t k = 0; k < estimate.size(); ++k) {
      if (!estimate[k].shape || !t.shape) continue;
      const double overlap = estimate[k].Area() * AreaOn(*estimate[k].shape, *t.shape, kOnTrueEmitter);
      if (overlap > 0) matched[k] = true;
      const double iou = overlap / (estimate[k].Area() + t.Area() - overlap);
      if (iou > es.iou) es.iou = iou, es.power_ratio = Lum(estimate[k].Power()) / Lum(t.Power());
    }
    s->emitters.push_back(es);
  }
  double total = 0;
  for (const EmitterLight& e : estimate) total += Lum(e.Power());
  for (std::size_t k = 0; k < estimate.size(); ++k)
    if (!matched[k] && total > 0) s->spurious_emitter_share = std::max(s->spurious_emitter_share, Lum(estimate[k].Power()) / total);
  s->estimated_emitters = static_cast<int>(estimate.size());
}

/// Each true sun against the nearest estimated directional light.
void ScoreSuns(const TrueLamps& truth, const std::vector<DirectionalLight>& estimate, ScanScore* s) {
  for (const DirectionalLight& t : truth.suns) {
    SunScore ss;
    ss.truth = t.direction;
    for (const DirectionalLight& e : estimate) {
      const double angle = AngleDeg(e.direction, t.direction);
      if (angle < ss.angle_deg) {
        ss.angle_deg = angle;
        ss.irradiance_ratio = Lum(e.irradiance) / Lum(t.irradiance);
      }
    }
    s->suns.push_back(ss);
  }
}

/// `image` blurred by a Gaussian of `sigma` pixels over the pixels `valid` marks (normalised
/// convolution: the others neither give nor take; they come out as they were).
ImageRGB BlurOver(const ImageRGB& image, const std::vector<std::uint8_t>& valid, double sigma) {
  const int w = image.width, h = image.height, r = static_cast<int>(std::ceil(3 * sigma));
  std::vector<float> kernel(2 * r + 1);
  for (int k = -r; k <= r; ++k) kernel[k + r] = static_cast<float>(std::exp(-0.5 * k * k / (sigma * sigma)));
  // Channels 0-2 the colour times the weight, 3 the weight; x then y.
  std::vector<float> a(4 * static_cast<std::size_t>(w) * h, 0.f), b(a.size(), 0.f);
  for (std::size_t p = 0; p < valid.size(); ++p)
    if (valid[p]) {
      for (int c = 0; c < 3; ++c) a[4 * p + c] = image.data[3 * p + c];
      a[4 * p + 3] = 1;
    }
  const auto pass = [&](const std::vector<float>& in, std::vector<float>& out, int dx, int dy) {
    ParallelFor(0, h, [&](std::size_t yy) {
      const int y = static_cast<int>(yy);
      for (int x = 0; x < w; ++x) {
        float sum[4] = {0, 0, 0, 0};
        for (int k = -r; k <= r; ++k) {
          const int sx = x + k * dx, sy = y + k * dy;
          if (sx < 0 || sy < 0 || sx >= w || sy >= h) continue;
          const float* v = &in[4 * (static_cast<std::size_t>(sy) * w + sx)];
          for (int c = 0; c < 4; ++c) sum[c] += kernel[k + r] * v[c];
        }
        std::copy(sum, sum + 4, &out[4 * (static_cast<std::size_t>(y) * w + x)]);
      }
    });
  };
  pass(a, b, 1, 0);
  pass(b, a, 0, 1);
  ImageRGB out = image;
  for (std::size_t p = 0; p < valid.size(); ++p)
    if (valid[p] && a[4 * p + 3] > 0)
      for (int c = 0; c < 3; ++c) out.data[3 * p + c] = a[4 * p + c] / a[4 * p + 3];
  return out;
}

/// Per pixel of the held-out view, the albedo where its ray first hits `tracer`'s mesh; NaN
/// for a pixel outside the mask or hitting nothing (the reconstruction does not cover it).
std::vector<Eigen::Vector3f> HitAlbedos(const RayTracer& tracer, const HeldOutView& held) {
  const Camera& c = held.view.camera;
  std::vector<Eigen::Vector3f> out(static_cast<std::size_t>(c.width) * c.height, Eigen::Vector3f::Constant(NAN));
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * c.width + x;
      SurfacePoint hit;
      if (held.view.valid[p] && tracer.Intersect(c.center(), c.RayDirection(x, y), &hit))
        out[p] = hit.albedo.cast<float>();
    }
  return out;
}

/// AlbedoScale on the hits HitAlbedos found.
double MedianAlbedoRatio(const std::vector<Eigen::Vector3f>& hits, const HeldOutView& held, int* samples) {
  if (samples) *samples = 0;
  const Camera& c = held.view.camera;
  if (held.true_albedo.width != c.width || held.true_albedo.height != c.height) return NAN;
  std::vector<double> ratios;
  for (std::size_t p = 0; p < hits.size(); ++p) {
    if (!hits[p].allFinite()) continue;
    const float* a = &held.true_albedo.data[3 * p];
    const double truth = Luminance(a[0], a[1], a[2]);
    if (truth > 1e-3) ratios.push_back(Lum(hits[p].cast<double>()) / truth);
  }
  if (samples) *samples = static_cast<int>(ratios.size());
  if (ratios.empty()) return NAN;
  std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
  return ratios[ratios.size() / 2];
}

/// ScanScore::albedo_error on the hits HitAlbedos found, the albedo divided by `scale`.
double AlbedoError(const std::vector<Eigen::Vector3f>& hits, const HeldOutView& held, double scale) {
  const Camera& c = held.view.camera;
  if (held.true_albedo.width != c.width || held.true_albedo.height != c.height || !(scale > 0)) return NAN;
  double err = 0, ref = 0;
  for (std::size_t p = 0; p < hits.size(); ++p) {
    if (!hits[p].allFinite()) continue;
    const Eigen::Vector3d truth(held.true_albedo.data[3 * p], held.true_albedo.data[3 * p + 1],
                                held.true_albedo.data[3 * p + 2]);
    if (Lum(truth) <= 1e-3) continue;  // as the scale's samples
    err += (hits[p].cast<double>() / scale - truth).squaredNorm();
    ref += truth.squaredNorm();
  }
  return ref > 0 ? std::sqrt(err / ref) : NAN;
}

/// AlbedoScale's scale and error on the hits HitAlbedos found.
double ScaleAndError(const std::vector<Eigen::Vector3f>& hits, const HeldOutView& held, int* samples, double* error) {
  const double scale = MedianAlbedoRatio(hits, held, samples);
  *error = AlbedoError(hits, held, scale);
  return scale;
}

}  // namespace

ImageRGB UpToTheClip(ImageRGB render, const View& held) {
  if (!std::isfinite(held.saturation)) return render;
  const float level = static_cast<float>(held.saturation);
  for (std::size_t i = 0; i < render.data.size(); ++i)
    if (held.image.data[i] >= level) render.data[i] = std::min(render.data[i], held.image.data[i]);
  return render;
}

namespace {

/// The held-out view relit under the run's estimate (`file`: its map, every light) on
/// `tracer`'s mesh, whose albedo each pixel hits is `hits`: its error over the view's
/// pixels, and over those the mesh covers (`covered`: their share).
void RelitError(const HeldOutView& held, const RayTracer& tracer, const std::vector<Eigen::Vector3f>& hits,
                const LightsFile& file, const fs::path& estimate_dir, const Eigen::Vector3d& up, int spp,
                ScanScore* s) {
  const EnvMap env(61, up);
  Lighting lighting{std::vector<double>(3 * env.size(), 0.0), file.lights};
  if (!file.environment.empty()) lighting.map = env.FromEquirect(ReadEquirectMap(estimate_dir / file.environment));
  TracerOptions t;
  t.spp = spp, t.seed = 1, t.bounces = kRenderBounces;
  const CellSampler sampler(env, lighting.map, {}, 0.2);
  const ImageRGB rendered = RenderLighting(tracer, env, lighting, sampler, {held.view}, t, false)[0];
  WritePngSrgb(estimate_dir.parent_path() / "held_out_relit.png", rendered);
  const ImageRGB image = UpToTheClip(rendered, held.view);
  s->held_out_relit = RelativeImageRmse(image, held.view.image, held.view.valid);
  const Camera& c = held.view.camera;
  std::vector<std::uint8_t> covered = held.view.valid;
  // The light's part: each covered pixel's shading (the render over the albedo it hit)
  // times the true albedo there, so the colour map's own errors drop out.
  const bool true_albedo = held.true_albedo.width == c.width && held.true_albedo.height == c.height;
  ImageRGB shaded_true = rendered;
  long in_view = 0, hit = 0;
  for (std::size_t p = 0; p < covered.size(); ++p) {
    if (!covered[p]) continue;
    ++in_view;
    covered[p] = hits[p].allFinite();
    hit += covered[p];
    if (!covered[p] || !true_albedo) continue;
    float* out = &shaded_true.data[3 * p];
    const float* a = &held.true_albedo.data[3 * p];
    for (int ch = 0; ch < 3; ++ch) out[ch] = hits[p][ch] > 1e-3f ? out[ch] / hits[p][ch] * a[ch] : 0.f;
  }
  s->held_out_covered = in_view ? static_cast<double>(hit) / in_view : 0;
  s->held_out_relit_covered = RelativeImageRmse(image, held.view.image, covered);
  const BlurSplit split = SplitByBlur(image, held.view.image, covered);
  s->held_out_relit_blurred = split.smooth;
  s->held_out_colour_map_part = split.sharp;
  if (!true_albedo) return;
  // At the one scale that fits best (light x albedo is what the images fix; the scale's
  // share of the error is in light_times_albedo).
  double num = 0, den = 0;
  const float level = static_cast<float>(held.view.saturation);  // (a clipped channel sets no scale)
  for (std::size_t p = 0; p < covered.size(); ++p)
    if (covered[p])
      for (int ch = 0; ch < 3; ++ch) {
        if (held.view.image.data[3 * p + ch] >= level) continue;
        num += static_cast<double>(shaded_true.data[3 * p + ch]) * held.view.image.data[3 * p + ch];
        den += static_cast<double>(shaded_true.data[3 * p + ch]) * shaded_true.data[3 * p + ch];
      }
  s->held_out_true_albedo_scale = den > 0 ? num / den : NAN;
  for (float& v : shaded_true.data) v = static_cast<float>(v * s->held_out_true_albedo_scale);
  shaded_true = UpToTheClip(std::move(shaded_true), held.view);
  s->held_out_relit_true_albedo = RelativeImageRmse(shaded_true, held.view.image, covered);
}

}  // namespace

HeldOutView ReadHeldOutView(const fs::path& holdout_json) {
  const json j = ReadJsonFile(holdout_json);
  const fs::path dir = holdout_json.parent_path();
  HeldOutView h;
  Camera& c = h.view.camera;
  c.width = static_cast<int>(Number(j, "width", holdout_json));
  c.height = static_cast<int>(Number(j, "height", holdout_json));
  c.fx = Number(j, "fx", holdout_json), c.fy = Number(j, "fy", holdout_json);
  c.cx = Number(j, "cx", holdout_json), c.cy = Number(j, "cy", holdout_json);
  const json& T = j.at("world_from_camera");
  if (!T.is_array() || T.size() != 4) throw InputError(holdout_json.string(), "\"world_from_camera\" must be 4x4");
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 4; ++k) c.world_from_camera(r, k) = T[r][k].get<double>();
  if (!j.contains("image") || !j["image"].is_string()) throw InputError(holdout_json.string(), "no \"image\"");
  ImageEncoding encoding = ImageEncoding::kLinearFloat;
  h.view.image = ReadImageLinear(dir / j["image"].get<std::string>(), &encoding);
  // An integer image is clipped at its top code (as a bundle's view; scene_bundle.cpp).
  if (encoding != ImageEncoding::kLinearFloat) h.view.saturation = 1.0;
  if (h.view.image.width != c.width || h.view.image.height != c.height)
    throw InputError(holdout_json.string(), "the image's size is not the camera's");
  h.view.valid.assign(static_cast<std::size_t>(c.width) * c.height, 1);
  if (j.contains("mask") && j["mask"].is_string()) {
    const Mask m = ReadMask(dir / j["mask"].get<std::string>());
    if (m.width != c.width || m.height != c.height) throw InputError(holdout_json.string(), "the mask's size is not the camera's");
    for (std::size_t p = 0; p < m.data.size(); ++p) h.view.valid[p] = m.data[p] != 0;
  }
  if (j.contains("albedo") && j["albedo"].is_string()) h.true_albedo = ReadImageLinear(dir / j["albedo"].get<std::string>());
  return h;
}

MeshError CompareMeshes(const Mesh& reconstructed, const Mesh& truth, const std::vector<Camera>& seen_from) {
  MeshError e;
  const std::vector<float> accuracy = NearestDistances(reconstructed.positions, SurfacePoints(truth, 0.005));
  e.median_m = Percentile(accuracy, 0.5);
  e.p90_m = Percentile(accuracy, 0.9);
  std::vector<Eigen::Vector3f> seen;
  if (seen_from.empty()) {
    seen = SurfacePoints(truth, 0.01);
  } else {
    const RayTracer tracer(truth);
    for (const Camera& c : seen_from)
      for (int y = 0; y < c.height; y += 4)
        for (int x = 0; x < c.width; x += 4) {
          SurfacePoint hit;
          if (tracer.Intersect(c.center(), c.RayDirection(x, y), &hit)) seen.push_back(hit.position.cast<float>());
        }
  }
  const std::vector<float> completeness = NearestDistances(seen, reconstructed.positions);
  e.complete_2cm = seen.empty() ? NAN
                                : std::count_if(completeness.begin(), completeness.end(), [](float d) { return d < 0.02f; }) /
                                      static_cast<double>(seen.size());
  return e;
}

BlurSplit SplitByBlur(const ImageRGB& image, const ImageRGB& reference, const std::vector<std::uint8_t>& valid,
                      double sigma_px) {
  BlurSplit s;
  s.total = RelativeImageRmse(image, reference, valid);
  s.smooth = RelativeImageRmse(BlurOver(image, valid, sigma_px), BlurOver(reference, valid, sigma_px), valid);
  if (std::isfinite(s.total) && std::isfinite(s.smooth))
    s.sharp = std::sqrt(std::max(0.0, s.total * s.total - s.smooth * s.smooth));
  return s;
}

double AlbedoScale(const Mesh& mesh, const HeldOutView& held, int* samples, double* error) {
  const RayTracer tracer(mesh);
  double e = NAN;
  const double scale = ScaleAndError(HitAlbedos(tracer, held), held, samples, &e);
  if (error) *error = e;
  return scale;
}

ScanScore EvaluateScan(const fs::path& truth_dir, const fs::path& run_dir, int spp) {
  Stopwatch sw;
  ScanScore s;
  // The cheap input's errors first; without truth.json (a real recording's held-out frame)
  // no light is scored, without any truth nothing can be.
  const bool has_lights = fs::exists(truth_dir / "truth.json"), has_mesh = fs::exists(truth_dir / "gt_mesh.ply"),
             has_held_out = fs::exists(truth_dir / "holdout" / "holdout.json");
  if (!has_lights && !has_mesh && !has_held_out)
    throw InputError(truth_dir.string(), "no truth.json, gt_mesh.ply nor holdout/holdout.json: nothing to score against");
  const TrueLamps truth = has_lights ? ReadTrueLamps(truth_dir / "truth.json") : TrueLamps{};
  const fs::path scene_dir = run_dir / "scene", estimate_dir = run_dir / "estimate";
  const SceneBundle bundle = LoadSceneBundle(scene_dir);
  if (has_mesh) {
    Mesh truth = ReadPly(truth_dir / "gt_mesh.ply");
    SanitizeMesh(&truth, (truth_dir / "gt_mesh.ply").string());
    std::vector<Camera> cameras;
    for (const View& v : bundle.views) cameras.push_back(v.camera);
    s.mesh = CompareMeshes(bundle.mesh, truth, cameras);
  }
  const fs::path lights_path = estimate_dir / "lights.json";
  const LightsFile lights = ReadLightsFile(lights_path);
  ScoreLamps(truth, OfKind<PointLight>(lights.lights), &s);
  if (!has_lights) s.spurious_share = NAN;  // no truth: no lamp is known spurious
  ScoreSuns(truth, OfKind<DirectionalLight>(lights.lights), &s);
  ScoreEmitters(truth.emitters, OfKind<EmitterLight>(lights.lights), &s);
  const fs::path albedo_mesh = estimate_dir / "albedo_mesh.ply";
  Mesh lit = fs::exists(albedo_mesh) ? ReadPly(albedo_mesh) : bundle.mesh;
  SanitizeMesh(&lit, albedo_mesh.string());
  if (lit.normals.size() != lit.positions.size()) ComputeVertexNormals(&lit);
  if (has_held_out) {
    const HeldOutView held = ReadHeldOutView(truth_dir / "holdout" / "holdout.json");
    const std::vector<std::uint8_t> open = TrianglesOnShapes(lit, lights.openings);  // (as render --lights)
    const RayTracer tracer(std::move(lit), open);
    const std::vector<Eigen::Vector3f> hits = HitAlbedos(tracer, held);
    s.albedo_scale = ScaleAndError(hits, held, &s.albedo_samples, &s.albedo_error);
    RelitError(held, tracer, hits, lights, estimate_dir, bundle.up, spp, &s);
  }
  for (LampScore& l : s.lamps) l.light_times_albedo = l.intensity_ratio * s.albedo_scale;
  s.seconds = sw.Seconds();
  return s;
}

namespace {

json ScoreJson(const ScanScore& s) {
  const auto num = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  const auto vec = [](const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); };
  json j;
  if (s.mesh)
    j["mesh"] = {{"median_m", num(s.mesh->median_m)}, {"p90_m", num(s.mesh->p90_m)},
                 {"complete_2cm", num(s.mesh->complete_2cm)}};
  j["lamps"] = json::array();
  for (const LampScore& l : s.lamps)
    j["lamps"].push_back({{"truth", vec(l.truth)},
                          {"estimate", std::isfinite(l.error_m) ? vec(l.estimate) : json(nullptr)},
                          {"distance_m", l.distance_m},
                          {"error_m", num(l.error_m)}, {"error_share", num(l.share)},
                          {"intensity_ratio", num(l.intensity_ratio)}, {"light_times_albedo", num(l.light_times_albedo)}});
  j["suns"] = json::array();
  for (const SunScore& u : s.suns)
    j["suns"].push_back({{"truth", vec(u.truth)}, {"angle_deg", num(u.angle_deg)},
                         {"irradiance_ratio", num(u.irradiance_ratio)}});
  j["emitters"] = json::array();
  for (const EmitterScore& e : s.emitters)
    j["emitters"].push_back({{"true_area_m2", e.true_area}, {"iou", e.iou}, {"power_ratio", num(e.power_ratio)}});
  j["estimated_emitters"] = s.estimated_emitters;
  j["spurious_emitter_share"] = num(s.spurious_emitter_share);
  j["estimated_lamps"] = s.estimated_lamps;
  j["spurious_share"] = num(s.spurious_share);
  j["albedo_scale"] = num(s.albedo_scale);
  j["albedo_samples"] = s.albedo_samples;
  j["albedo_error"] = num(s.albedo_error);
  j["held_out_relit"] = num(s.held_out_relit);
  j["held_out_covered"] = num(s.held_out_covered);
  j["held_out_relit_covered"] = num(s.held_out_relit_covered);
  j["held_out_relit_true_albedo"] = num(s.held_out_relit_true_albedo);
  j["held_out_true_albedo_scale"] = num(s.held_out_true_albedo_scale);
  j["held_out_relit_blurred"] = num(s.held_out_relit_blurred);
  j["held_out_colour_map_part"] = num(s.held_out_colour_map_part);
  j["seconds"] = s.seconds;
  return j;
}

}  // namespace

std::string ScanScoreJson(const ScanScore& s) { return ScoreJson(s).dump(2) + "\n"; }

bool AddToReport(const fs::path& run_dir, const ScanScore& s) {
  const fs::path report = run_dir / "estimate" / "report.json";
  if (!fs::exists(report)) return false;
  json j = ReadJsonFile(report);
  j["evaluation"] = ScoreJson(s);
  WriteTextAtomically(report, j.dump(2) + "\n");
  return true;
}

}  // namespace lp::app
