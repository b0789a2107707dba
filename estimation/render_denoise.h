#pragma once
/// A render's Monte Carlo noise smoothed out, guided by what each pixel sees: the clean
/// render's denoiser (issue 44). A pixel's radiance is its albedo times its irradiance; the
/// irradiance varies slowly across a surface and its noise from pixel to pixel, so it is
/// averaged over neighbouring pixels that see the same surface (near the pixel's tangent
/// plane, normals alike), and multiplied back by the pixel's own albedo: texture, edges and
/// the map seen directly stay sharp. The lights' direct light (sharp shadows) is taken out
/// before and put back after, traced for the guide with 16 shadow rays a pixel: what is
/// smoothed is the map's and the bounces' light, whose shadows are soft. Pixels on a sharp
/// shadow's edge are kept as traced (the guide's coverage of the edge is rough). (The map's
/// brightest cells taken out as discs too made it worse: a disc's few shadow rays are noise
/// in the guide, put back unsmoothed and common to both halves, so unseen by the noise said.)
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "estimation/lights/light.h"
#include "scene/camera.h"
#include "scene/ray_tracer.h"

namespace lp {

/// What each pixel of a camera sees, averaged over the pixel as the renders' box filter
/// (4 x 4 stratified rays): albedo, shading normal (not renormalized: shorter where the
/// pixel spans a crease), hit point, the share of its rays that hit the mesh, and the
/// radiance `lights` send it directly (albedo / pi times their irradiance, as the renderers
/// add it at a path's first surface).
struct PixelGuide {
  int width = 0, height = 0;
  std::vector<Eigen::Vector3f> albedo, normal, position, direct;
  std::vector<float> hit_share;
};

PixelGuide GuideOf(const RayTracer& scene, const Camera& camera, const std::vector<Light>& lights);

struct DenoiseOptions {
  int radius = 2;            ///< pixels: the window is (2 radius + 1)^2
  double sigma = 1.0;        ///< pixels: a neighbour weighs exp(-r^2 / (2 sigma^2))
  double max_plane_distance = 0.02;  ///< a neighbour's hit this far from the pixel's tangent plane, per metre of depth, is another surface
  double min_normal_cosine = 0.9;    ///< ... and one whose normal turns more is too
};

/// `image` (a mean radiance) with each wholly covered pixel off a shadow's edge (its direct
/// irradiance within a tenth of its 8 neighbours') given its light but the lights' direct
/// light, over its albedo (per channel), averaged over its window's pixels on the same
/// surface, times its albedo again, plus the guide's direct light. Pixels not wholly on
/// the mesh, or of albedo below 1e-3 in a channel, keep their value there. Affine in
/// `image`: two independent renders denoised alike differ by their noises smoothed.
ImageRGB Denoise(const ImageRGB& image, const PixelGuide& guide, const Eigen::Vector3d& camera_centre,
                 const DenoiseOptions& options = {});

}  // namespace lp
