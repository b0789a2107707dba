#pragma once
/// Renders under the lights (every kind, estimation/lights/light.h) beside the map: the
/// forward model of the lights' columns, and the final relit render.
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

/// Renders each view under the lights alone, of any kind (every pixel when `all_pixels`,
/// else only the valid ones): the forward model of the columns, with options.spp paths per
/// pixel.
std::vector<ImageRGB> RenderLights(const RayTracer& scene, const std::vector<View>& views,
                                   const std::vector<Light>& lights, const TracerOptions& options, bool all_pixels,
                                   TraceStats* stats = nullptr);

}  // namespace lp
