#pragma once
/// One RGB-D frame as a source delivers it (owned, copyable).
#include <cstdint>
#include <optional>

#include <Eigen/Core>

#include "common/image.h"

namespace lp {

/// Pinhole intrinsics of one stream (pixels, OpenCV convention, pixel centres at integers).
struct Intrinsics {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

struct RgbdFrame {
  std::int64_t index = 0;        ///< 0-based, in the order the source produced them
  DepthImage depth;              ///< uint16 millimetres, 0 = invalid
  ImageRgb8 color;               ///< 8-bit sRGB as the camera encodes it
  double depth_timestamp = 0;    ///< seconds, the device's clock (or the file's)
  double color_timestamp = 0;
  Intrinsics depth_intrinsics, color_intrinsics;
  /// Depth is registered to colour: depth pixel (x, y) sees what colour pixel (x, y) sees,
  /// and depth_intrinsics == color_intrinsics.
  bool registered = false;
  /// The colour camera's exposure and gain (device units) when the source knows them
  /// (a live device after locking, a recording's side file); 0 = unknown.
  double exposure = 0, gain = 0;
  /// The true pose when the source knows it (synthetic frames, a trajectory file).
  std::optional<Eigen::Matrix4d> world_from_camera;
  /// Host steady-clock seconds when the capture thread queued the frame (0 if never
  /// queued): for measuring the latency to the consumer.
  double queued_at = 0;
};

}  // namespace lp
