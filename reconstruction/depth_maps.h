#pragma once
/// Depth preprocessing for tracking and fusion: a bilateral filter, then a pyramid of
/// depth, vertex and normal maps (KinectFusion's measurement stage).

#include <vector>

#include <Eigen/Core>

#include "capture/frame.h"
#include "common/image.h"

namespace lp {

struct PreprocessOptions {
  int levels = 3;               ///< pyramid levels (level 0 = full resolution)
  int bilateral_radius = 2;     ///< pixels (5x5 window)
  float sigma_space = 4.5f;     ///< pixels
  float sigma_depth = 0.03f;    ///< metres
  float min_depth = 0.2f;       ///< metres; nearer readings are dropped
  float max_depth = 5.0f;       ///< metres; farther readings are dropped
  int normal_radius = 2;        ///< first-level normals from +-2 pixels (coarser levels: +-1)
  /// The finest level that gets filtered and gets vertex / normal maps (tracking starts
  /// there); finer levels hold the unfiltered depth only. 1 suits 640x480 frames.
  int first_level = 0;
};

/// One pyramid level, camera frame. Invalid entries: depth 0, vertex / normal NaN.
struct DepthLevel {
  Camera k;                         ///< scaled to this level
  std::vector<float> depth;             ///< metres along the optical axis
  std::vector<Eigen::Vector3f> vertex;  ///< camera frame, metres
  std::vector<Eigen::Vector3f> normal;  ///< camera frame, unit, facing the camera
  /// Levels finer than PreprocessOptions::first_level have depth but no maps (empty).
  bool has_maps() const { return !normal.empty(); }
  bool valid(std::size_t p) const { return depth[p] > 0 && normal[p].x() == normal[p].x(); }
};

/// Millimetres to metres, outside [min_depth, max_depth] dropped (no filtering).
std::vector<float> DepthToMetres(const DepthImage& depth, const PreprocessOptions& options);

/// Bilateral filter of a depth map (metres, 0 = invalid): neighbours further than
/// 3 sigma_depth in depth do not contribute, invalid pixels stay invalid.
std::vector<float> BilateralFilter(const std::vector<float>& depth, int width, int height,
                                   const PreprocessOptions& options);

/// Vertex and normal maps for a depth map (normals from central differences over
/// +-normal_radius pixels, invalid at depth discontinuities and the border).
void ComputeVertexNormalMaps(DepthLevel* level, int normal_radius = 1);

/// The whole measurement stage: metres, then each coarser level by 2x2 averaging of depths
/// within 3 sigma_depth of the block's first valid one; the bilateral filter at
/// `first_level`, and vertex and normal maps from there on.
std::vector<DepthLevel> PreprocessDepth(const DepthImage& depth, const Camera& k, const PreprocessOptions& options);

/// A depth map (metres, 0 = none) at pyramid level `level`: each pixel the nearest depth of
/// its 2^level x 2^level block, 0 where any of the block has none.
std::vector<float> NearestDepthAtLevel(const std::vector<float>& depth, int width, int height, int level);

/// Intrinsics of pyramid level `level` (each level halves the size).
Camera ScaleIntrinsics(const Camera& k, int level);

}  // namespace lp
