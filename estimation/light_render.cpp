#include "estimation/light_render.h"

#include "common/error.h"
#include "estimation/lights/light.h"
#include "estimation/pixel_loop.h"

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
  return RenderEnvironment(scene, env, views, lighting.map, sampler, options, all_pixels, lamps, stats);
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
      WalkPath(scene, cam, x, y, rng, opt, cnt,
               [&](const SurfacePoint& hit, const Eigen::Vector3d& off, const Eigen::Vector3d& w) {
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
