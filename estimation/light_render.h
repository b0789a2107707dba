#pragma once
/// Renders under the lights (every kind, estimation/lights/light.h) beside the map: the
/// forward model of the lights' columns, and the final relit render.
#include <vector>

#include "common/image.h"
#include "estimation/envmap.h"
#include "estimation/lights/light.h"
#include "estimation/path_tracer.h"
#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"

namespace lp {

/// Renders each view under the map (`lambda`, 3 per cell of `env`, NEE by `sampler`), the
/// point lights and the directional lights together, in one pass: at every vertex of the
/// map's paths, one shadow ray to each light (a jittered point of its disc). The same as
/// RenderEnvironment plus RenderPointLights, for about the map's cost alone.
std::vector<ImageRGB> RenderLighting(const RayTracer& scene, const EnvMap& env, const std::vector<double>& lambda,
                                     const CellSampler& sampler, const std::vector<PointLight>& lights,
                                     const std::vector<DirectionalLight>& directional, const std::vector<View>& views,
                                     const TracerOptions& options, bool all_pixels, TraceStats* stats = nullptr);

/// Renders each view under the point lights and the directional ones (every pixel when
/// `all_pixels`, else only the valid ones): the forward model of the columns, with
/// options.spp paths per pixel.
std::vector<ImageRGB> RenderPointLights(const RayTracer& scene, const std::vector<View>& views,
                                        const std::vector<PointLight>& lights, const TracerOptions& options,
                                        bool all_pixels, TraceStats* stats = nullptr,
                                        const std::vector<DirectionalLight>& directional = {});

}  // namespace lp
