#include "estimation/light_render.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"
#include "common/parallel.h"
#include "common/timer.h"
#include "estimation/lights/light.h"
#include "estimation/pixel_loop.h"
#include "estimation/render_denoise.h"

namespace lp {

using detail::Counters;
using detail::ForEachPixel;
using detail::PixelRef;
using detail::PixelsToTrace;
using detail::CheckPathOptions;
using detail::WalkPath;

std::vector<ImageRGB> RenderLighting(const RayTracer& scene, const EnvMap& env, const Lighting& lighting,
                                     const CellSampler& sampler, const std::vector<View>& views,
                                     const TracerOptions& options, bool all_pixels, TraceStats* stats) {
  VertexLight lamps;
  if (!lighting.lights.empty())
    lamps = [&](const SurfacePoint& hit, const Eigen::Vector3d& off, std::uint64_t key, std::int64_t& rays) {
      return Irradiance(scene, lighting.lights, off, hit.shading, hit.geometric, key, &rays);
    };
  SeenLight seen;
  if (lighting.Count<EmitterLight>() > 0)
    seen = [&](const SurfacePoint& hit) { return Emission(lighting.lights, hit.position, hit.geometric); };
  std::vector<ImageRGB> out =
      RenderEnvironment(scene, env, views, lighting.map, sampler, options, all_pixels, lamps, stats, seen);
  AddPanesInHoles(scene, lighting.lights, views, all_pixels, &out);
  return out;
}

void AddPanesInHoles(const RayTracer& scene, const std::vector<Light>& lights, const std::vector<View>& views,
                     bool all_pixels, std::vector<ImageRGB>* images) {
  std::vector<EmitterLight> panes;
  for (const EmitterLight& e : OfKind<EmitterLight>(lights))
    if (e.in_a_hole) panes.push_back(e);
  if (panes.empty()) return;
  const std::vector<detail::PixelRef> pixels = PixelsToTrace(views, all_pixels);
  ParallelForChunks(0, pixels.size(), 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const Camera& cam = views[pixels[i].view].camera;
      const int x = pixels[i].pixel % cam.width, y = pixels[i].pixel / cam.width;
      const Eigen::Vector3d dir = cam.RayDirection(x, y);
      const auto seen = [&](double before) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (const EmitterLight& pane : panes) sum += SeenInAHole(pane, cam.center(), dir, before);
        return sum;
      };
      if (seen(std::numeric_limits<double>::infinity()).isZero()) continue;  // (crosses none: no scene ray)
      SurfacePoint hit;
      const Eigen::Vector3d sum =
          seen(scene.Intersect(cam.center(), dir, &hit) ? hit.distance : std::numeric_limits<double>::infinity());
      float* p = (*images)[pixels[i].view].at(x, y);
      for (int c = 0; c < 3; ++c) p[c] += static_cast<float>(sum[c]);
    }
  });
}

namespace {

/// The mean of two halves' sums over `n` samples each into `mean`, and its relative noise:
/// the RMS of half their means' difference over the views' valid pixels and channels, over
/// the mean's mean there.
double MeanAndNoise(const std::vector<ImageRGB>& a, const std::vector<ImageRGB>& b, int n,
                    const std::vector<View>& views, std::vector<ImageRGB>* mean) {
  *mean = a;
  double sq = 0, sum = 0;
  std::size_t count = 0;
  for (std::size_t v = 0; v < views.size(); ++v)
    for (std::size_t p = 0; p < a[v].pixels(); ++p)
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = 3 * p + c;
        const double x = a[v].data[i] / n, y = b[v].data[i] / n;
        (*mean)[v].data[i] = static_cast<float>(0.5 * (x + y));
        if (!views[v].valid.empty() && !views[v].valid[p]) continue;
        sq += 0.25 * (x - y) * (x - y);
        sum += 0.5 * (x + y);
        ++count;
      }
  return count > 0 && sum > 0 ? std::sqrt(sq / count) / (sum / count) : 0.0;
}

/// `sum` += `add` x `weight`, image by image.
void Accumulate(std::vector<ImageRGB>* sum, const std::vector<ImageRGB>& add, double weight) {
  if (sum->empty()) {
    *sum = add;
    for (ImageRGB& im : *sum)
      for (float& x : im.data) x = static_cast<float>(x * weight);
    return;
  }
  for (std::size_t v = 0; v < add.size(); ++v)
    for (std::size_t i = 0; i < add[v].data.size(); ++i) (*sum)[v].data[i] += static_cast<float>(add[v].data[i] * weight);
}

}  // namespace

std::vector<ImageRGB> ProgressiveRender(const RayTracer& scene, const EnvMap& env, const Lighting& lighting,
                                        const CellSampler& sampler, const std::vector<View>& views,
                                        const TracerOptions& options, double noise, double seconds, int max_spp,
                                        std::vector<RenderPass>* passes, const RenderPassCallback& on_pass,
                                        bool denoise) {
  Stopwatch clock;
  std::vector<Denoiser> denoisers;
  if (denoise)
    for (const View& v : views) denoisers.emplace_back(GuideOf(scene, v.camera, lighting.lights), v.camera.center());
  const auto denoised_mean = [&](const std::vector<ImageRGB>& sums, int n) {  // sums over n samples
    std::vector<ImageRGB> out = sums;
    for (std::size_t v = 0; v < sums.size(); ++v) {
      for (float& x : out[v].data) x /= static_cast<float>(n);
      out[v] = denoisers[v](out[v]);
    }
    return out;
  };
  std::vector<ImageRGB> half[2], mean;
  TracerOptions o = options;
  o.first_vertex_lights = !denoise;  // the guide's direct light instead
  int each = 0;  // samples per pixel in each half so far
  passes->clear();
  for (int pass = 0;; ++pass) {
    const double start = clock.Seconds();
    for (int h = 0; h < 2; ++h) {
      o.seed = options.seed * 1000003ull + 2 * static_cast<std::uint64_t>(pass) + h;
      Accumulate(&half[h], RenderLighting(scene, env, lighting, sampler, views, o, true), o.spp);
    }
    each += o.spp;
    const double took = clock.Seconds() - start;
    const double noise_now = denoise ? MeanAndNoise(denoised_mean(half[0], each), denoised_mean(half[1], each), 1, views, &mean)
                                     : MeanAndNoise(half[0], half[1], each, views, &mean);
    passes->push_back({2 * each, clock.Seconds(), noise_now});
    if (on_pass) on_pass(passes->back(), mean);
    // The next pass: twice this one, or (the noise falling as one over the root of the
    // samples) what reaches the noise asked with a tenth to spare, whichever is less; at
    // most what the time left holds at this pass's pace (a tenth to spare), and none when
    // that is under an eighth of this pass.
    double next = 2.0 * o.spp;
    if (noise > 0 && noise_now > 0)
      next = std::clamp(std::ceil(each * (1.1 * std::pow(noise_now / noise, 2) - 1)), o.spp / 4.0, next);
    next = std::min(next, std::floor(0.9 * (seconds - clock.Seconds()) / std::max(took, 1e-9) * o.spp));
    if (noise_now <= noise || next < std::max(1.0, o.spp / 8.0) || 2 * (each + next) > max_spp) return mean;
    o.spp = static_cast<int>(next);
  }
}

std::vector<ImageRGB> RenderLights(const RayTracer& scene, const std::vector<View>& views,
                                   const std::vector<Light>& lights, const TracerOptions& opt, bool all_pixels,
                                   TraceStats* stats) {
  CheckPathOptions(opt);
  std::vector<ImageRGB> out;
  for (const View& v : views) out.emplace_back(v.camera.width, v.camera.height);
  const std::vector<PixelRef> pixels = PixelsToTrace(views, all_pixels);
  ForEachPixel(pixels, opt, stats, [&](std::size_t, const PixelRef& px, Counters& cnt) {
    const Camera& cam = views[px.view].camera;
    const int x = px.pixel % cam.width, y = px.pixel / cam.width;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int s = 0; s < opt.spp; ++s) {
      Rng rng(opt.seed, px.view, px.pixel, s);
      std::uint64_t key = (static_cast<std::uint64_t>(px.pixel) << 32) ^ (static_cast<std::uint64_t>(s) << 8);
      bool first = true;
      WalkPath(scene, cam, x, y, rng, opt, cnt,
               [&](const SurfacePoint& hit, const Eigen::Vector3d& off, const Eigen::Vector3d& w) {
                 if (first) sum += Emission(lights, hit.position, hit.geometric);
                 first = false;
                 sum += w.cwiseProduct(
                     Irradiance(scene, lights, off, hit.shading, hit.geometric, ++key, &cnt.rays));
               });
    }
    float* p = out[px.view].at(x, y);
    for (int c = 0; c < 3; ++c) p[c] = static_cast<float>(sum[c] / opt.spp);
  });
  if (stats) stats->pixels_traced += static_cast<std::int64_t>(pixels.size());
  return out;
}

}  // namespace lp
