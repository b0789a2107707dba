#pragma once
/// Windows the cameras saw as holes (issue 43): clear glass returns no depth, so a window is
/// a blob of clipped pixels off the mesh whose rays leave the scene, ringed by one flat wall.
/// The directions that leave the room through that wall are the window's: beside one, the
/// map's prior is chosen for those cells (docs/method.md, "The map's prior").
#include <vector>

#include <Eigen/Core>

#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"

namespace lp {

struct SeenWindow {
  int view = 0;              ///< the view whose blob showed it (the largest, where several did)
  int pixels = 0;            ///< that blob's pixels
  Eigen::Vector3d centre;    ///< where the blob's mean ray crosses the wall's plane
  Eigen::Vector3d normal;    ///< the wall's unit normal, into the room (towards the camera)
  /// Where the rays through the pixel corners on the blob's outer boundary cross the wall's
  /// plane, each moved to the hole's edge in the mesh along the line from its centre (by up
  /// to 10 cm): the hole's outline (none where the wall is seen within 6 degrees of edge on).
  /// A window's rectangle in its wall: PortalOf.
  std::vector<Eigen::Vector3d> outline;
};

struct SeenWindowOptions {
  int min_pixels = 12;           ///< a blob's pixels at least
  /// Clipped pixels this close (pixels, on both axes) are one blob: the panes of one window
  /// between mullions a few pixels wide.
  int join = 4;
  double min_escape_share = 0.5;  ///< of the blob's pixels' rays (up to 64 of them) this share leave the scene
  int rim_rays = 24;             ///< rays cast on a ring around the blob's mean pixel
  double rim_scale = 1.5;        ///< the ring's radius: this times the blob's (sqrt(pixels / pi)), plus 2 pixels
  double near_scale = 1.15;      ///< where that ring finds no wall: one this times the blob's reach along each ray, plus 2
  double min_rim_share = 0.6;    ///< of the ring's rays at least this share hit the mesh ...
  double flat_share = 0.8;       ///< ... and of those this share lie on one plane:
  double flat_cos = 0.9;         ///< their normals within acos(0.9) = 26 degrees of their mean,
  double plane_distance = 0.05;  ///< their points within this (m) of the plane through their mean
  double merge = 0.3;            ///< windows closer than this (m), facing alike, are one
};

/// The windows of every view's blobs (ClippedBlobs, joined across `join` pixels) that are
/// mostly off the mesh, whose pixels' rays mostly leave the scene and whose ring of rays
/// meets one flat wall; one per place.
std::vector<SeenWindow> SeenWindows(const std::vector<View>& views, const RayTracer& scene,
                                    const SeenWindowOptions& options = {});

/// Whether `p` lies out beyond one of `windows`: behind its wall by more than `from`
/// (kBeyondWindow; negative: before it, in the room, by less than that) and within the cone
/// the hole opens onto (its rectangle, PortalOf, grown by the depth behind the wall on each
/// side; before the wall, the rectangle itself). A place
/// seen through the hole is the sky's, not a lamp's; a lamp on the window's wall, or in
/// another part of the room behind that wall's plane, is not.
constexpr double kBeyondWindow = 0.25;  // m
bool BeyondAWindow(const std::vector<SeenWindow>& windows, const Eigen::Vector3d& p, const Eigen::Vector3d& up,
                   double from = kBeyondWindow);

}  // namespace lp
