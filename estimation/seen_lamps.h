#pragma once
/// Lamps the cameras saw (issue 43): blobs of pixels the camera clipped give places to
/// propose point lights at, beside the search's grid around the scene (the data decides,
/// as for every candidate; docs/method.md, "A lamp where the camera saw it").
#include <string>
#include <vector>

#include <Eigen/Core>

#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"

namespace lp {

struct SeenLamp {
  Eigen::Vector3d position;
  /// "depth": a blob clipped on the mesh (a lamp's shade or bulb the depth camera saw), its
  /// surface a little towards the camera; "triangulated": a blob clipped off the mesh (a
  /// bulb that returned no depth) in two or more views, where their rays meet.
  std::string how;
  int views = 0;     ///< the views whose blobs placed it
  int pixels = 0;    ///< its blobs' pixels, over those views
  double gap = 0;    ///< triangulated: the largest distance between its rays and the place (m)
  /// Triangulated: the place's covariance (m^2), the rays' least-squares meeting point's
  /// with each blob's mean pixel kSeenPixelSigma off, plus the gap's square on every axis.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

/// A blob's mean pixel's standard error (pixels), in each direction: its edge pixels are
/// partly covered, and the bulb's glare is not quite round.
constexpr double kSeenPixelSigma = 0.5;

struct SeenLampOptions {
  int min_pixels = 1;               ///< a blob's pixels at least
  double max_view_share = 0.1;      ///< a blob's share of its view's pixels at most (a lamp is compact)
  double towards_camera = 0.02;     ///< "depth": the place this far (m) in front of the surface hit
  double min_angle_deg = 2;         ///< "triangulated": the rays at least this far apart
  double gap_base = 0.03;           ///< ... meeting within gap_base + gap_per_metre x distance (m)
  double gap_per_metre = 0.02;
  double merge = 0.1;               ///< places closer than this (m) are one, its pixels' mean
  int max_lamps = 8;                ///< the largest blobs' places at most
};

/// One blob: 8-connected pixels of one view that are `clipped` or `clipped_off` (View).
struct ClippedBlob {
  int view = 0;
  int pixels = 0;
  int off_mesh = 0;  ///< of them clipped off the mesh
  double u = 0, v = 0;  ///< the mean pixel (centres at integers)
  int min_x = 0, max_x = 0, min_y = 0, max_y = 0;  ///< its pixels' bounds
  std::vector<int> members;                          ///< its pixels (y * width + x)
};

/// The blobs of every view (none where a view carries no clipped pixels): clipped pixels
/// within `join` pixels of each other (on both axes; 1: 8-connected) are one blob.
std::vector<ClippedBlob> ClippedBlobs(const std::vector<View>& views, int join = 1);

/// Places for lamps where the cameras saw clipped blobs: a blob mostly on the mesh by the
/// mesh's surface along its mean pixel's ray; blobs mostly off it by triangulation across
/// views. The largest first, at most options.max_lamps.
std::vector<SeenLamp> SeenLamps(const std::vector<View>& views, const RayTracer& scene,
                                const SeenLampOptions& options = {});

}  // namespace lp
