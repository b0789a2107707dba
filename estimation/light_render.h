#pragma once
/// Renders under the lights (every kind, estimation/lights/light.h) beside the map: the
/// forward model of the lights' columns, and the final relit render.
#include <functional>
#include <vector>

#include "common/image.h"
#include "estimation/envmap.h"
#include "estimation/lighting.h"
#include "estimation/lights/light.h"
#include "estimation/path_tracer.h"
#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"

namespace lp {

/// Renders each view under `lighting`: its map (3 per cell of `env`, NEE by `sampler`) and
/// its lights together, in one pass: at every vertex of the map's paths, one shadow ray to
/// each light (a jittered point of its disc). The same as RenderEnvironment plus
/// RenderLights, for about the map's cost alone.
std::vector<ImageRGB> RenderLighting(const RayTracer& scene, const EnvMap& env, const Lighting& lighting,
                                     const CellSampler& sampler, const std::vector<View>& views,
                                     const TracerOptions& options, bool all_pixels, TraceStats* stats = nullptr);

/// Adds to each traced pixel (every pixel when `all_pixels`, else the valid ones) what its
/// centre's camera ray sees of the panes over holes among `lights` (SeenInAHole): a window
/// whose glass returned no depth, glowing, is seen through the hole, not on a surface.
/// RenderLighting does it; a render of the map alone shows what lies beyond.
void AddPanesInHoles(const RayTracer& scene, const std::vector<Light>& lights, const std::vector<View>& views,
                     bool all_pixels, std::vector<ImageRGB>* images);

/// One pass of ProgressiveRender: the samples per pixel so far, the seconds since it began,
/// and the estimated relative noise of the render so far.
struct RenderPass {
  int spp = 0;
  double seconds = 0, noise = 0;
};

/// A clean render of every pixel of `views` under `lighting` (RenderLighting), traced in
/// passes into two independent halves: options.spp samples a pixel each in the first pass;
/// each pass after it twice the last, or (the noise falling as one over the root of the
/// samples) what reaches `noise` with a tenth to spare, whichever is less; it stops when the
/// relative noise of the halves' mean (the RMS of half their difference over the valid
/// pixels and channels, over the mean's mean there) is at most `noise`, or the samples would
/// pass `max_spp`; a pass the time left before `seconds` cannot hold (at the last pass's
/// pace, a tenth to spare) is cut to what it holds, and not traced when that is under an
/// eighth of the last pass. Each pass is given to `on_pass` with the render so far (and
/// kept in `passes`). With `denoise`, both halves are denoised alike (Denoise,
/// estimation/render_denoise.h, one guide a view) before the mean and its noise are formed:
/// the noise said is the denoised render's (the denoiser's blur is not in it).
using RenderPassCallback = std::function<void(const RenderPass&, const std::vector<ImageRGB>&)>;
std::vector<ImageRGB> ProgressiveRender(const RayTracer& scene, const EnvMap& env, const Lighting& lighting,
                                        const CellSampler& sampler, const std::vector<View>& views,
                                        const TracerOptions& options, double noise, double seconds, int max_spp,
                                        std::vector<RenderPass>* passes, const RenderPassCallback& on_pass = {},
                                        bool denoise = false);

/// Renders each view under the lights alone, of any kind (every pixel when `all_pixels`,
/// else only the valid ones): the forward model of the columns, with options.spp paths per
/// pixel.
std::vector<ImageRGB> RenderLights(const RayTracer& scene, const std::vector<View>& views,
                                   const std::vector<Light>& lights, const TracerOptions& options, bool all_pixels,
                                   TraceStats* stats = nullptr);

}  // namespace lp
