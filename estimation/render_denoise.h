#pragma once
/// A render's Monte Carlo noise smoothed out, guided by what each pixel sees: the clean
/// render's denoiser (issue 44). A pixel's radiance is its albedo times its irradiance; the
/// irradiance varies slowly across a surface and its noise from pixel to pixel, so it is
/// fitted over neighbouring pixels that see the same surface (near the pixel's tangent
/// plane, normals alike) and multiplied back by the pixel's own albedo: texture, edges and
/// the map seen directly stay sharp. The lights' direct light at the first surface (sharp
/// shadows) is not in the render smoothed (TracerOptions::first_vertex_lights off): the
/// guide traces it over each pixel, 16 stratified rays, 144 where they disagree, and it is
/// added after. What is smoothed is the map's and the bounces' light, whose shadows are
/// soft. (The map's brightest cells taken out as discs too made it worse: a disc's few
/// shadow rays are noise in the guide, common to both halves, so unseen by the noise said.)
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "estimation/lights/light.h"
#include "scene/camera.h"
#include "scene/ray_tracer.h"

namespace lp {

/// What each pixel of a camera sees, averaged over the pixel as the renders' box filter
/// (4 x 4 stratified rays, 12 x 12 on the `fine` pixels): albedo, shading normal (not renormalized: shorter where the
/// pixel spans a crease), hit point, the share of its rays that hit the mesh, and the
/// radiance `lights` send it directly (albedo / pi times their irradiance, as the renderers
/// add it at a path's first surface).
struct PixelGuide {
  int width = 0, height = 0;
  std::vector<Eigen::Vector3f> albedo, normal, position, direct;
  std::vector<float> hit_share;
  /// Pixels traced again with 12 x 12 rays, where 4 x 4 give their mean only roughly: some
  /// rays missed the mesh, or the rays' albedo or direct light differ by a tenth in RMS (a
  /// texture's, a shadow's or the mesh's edge crosses the pixel), or the direct irradiance
  /// steps by more than a tenth to a neighbour (a sharp shadow's edge may pass between rays).
  std::vector<std::uint8_t> fine;
};

PixelGuide GuideOf(const RayTracer& scene, const Camera& camera, const std::vector<Light>& lights);

struct DenoiseOptions {
  int radius = 4;            ///< pixels: the window is (2 radius + 1)^2, radius at most 5
  double sigma = 2.0;        ///< pixels: a neighbour weighs exp(-r^2 / (2 sigma^2))
  double max_plane_distance = 0.02;  ///< a neighbour's hit this far from the pixel's tangent plane, per metre of depth, is another surface
  double min_normal_cosine = 0.9;    ///< ... and one whose normal turns more is too
  /// The fit's slopes held towards 0 by this share of the window's weight (per pixel of
  /// offset, per unit of the normal's tilt): where the window does not fix a slope (one
  /// row of pixels, normals all alike) it is 0 and the fit is the window's mean.
  double pixel_ridge = 0.01, normal_ridge = 1e-3;
};

/// The clean render's denoiser for one view: a render of the light but the lights' direct
/// light at the first surface (TracerOptions::first_vertex_lights off), made clean. Each
/// wholly covered pixel's irradiance there (its radiance over its albedo) is fitted, by
/// weighted least squares over its window's pixels on the same surface, as an affine
/// function of the pixel offset and of the normal's tilt, and its value at the pixel is
/// taken: a plain mean would blur the light's gradients and mix the light of normals that
/// differ (a scan's normals are noisy), the fit follows both. Then times the pixel's
/// albedo again (texture, edges and the map seen directly stay sharp), plus the guide's
/// direct light. Pixels not wholly on the mesh, or of albedo below 1e-3 in a channel, get
/// their value plus the direct light. The windows and fits depend on the guide alone and are
/// solved once; each image costs a weighted sum. Linear in `image`: two independent
/// renders denoised alike differ by their noises smoothed (the noise the clean render
/// says); the fit's bias (what the affine model misses) is not in it.
class Denoiser {
 public:
  Denoiser(PixelGuide guide, const Eigen::Vector3d& camera_centre, const DenoiseOptions& options = {});
  ImageRGB operator()(const ImageRGB& image) const;

 private:
  using Fit = Eigen::Matrix<float, 5, 1>;  // the fit's value at the pixel, per unit of each feature's moment
  PixelGuide g_;
  DenoiseOptions o_;
  std::vector<Eigen::Vector3f> unit_;           // the normals, normalized
  std::vector<std::uint64_t> window_;           // two words a pixel: the window's pixels on its surface
  std::vector<Fit> fit_;                        // NaN: the pixel keeps its value
  std::vector<float> weight_;                   // the window's Gaussian weights, row by row
};

/// Denoiser(guide, camera_centre, options)(image).
ImageRGB Denoise(const ImageRGB& image, const PixelGuide& guide, const Eigen::Vector3d& camera_centre,
                 const DenoiseOptions& options = {});

}  // namespace lp
