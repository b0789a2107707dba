#pragma once
/// One RGB-D frame as a source delivers it (owned, copyable).
#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "common/image.h"
#include "scene/camera.h"

namespace lp {

struct RgbdFrame {
  std::int64_t index = 0;        ///< 0-based, in the order the source produced them
  DepthImage depth;              ///< uint16 millimetres, 0 = invalid
  ImageRgb8 color;               ///< 8-bit sRGB as the camera encodes it
  double depth_timestamp = 0;    ///< seconds, the device's clock (or the file's)
  double color_timestamp = 0;
  /// Each stream's pinhole intrinsics (the pose is unused: the identity).
  Camera depth_intrinsics, color_intrinsics;
  /// Depth is registered to colour: depth pixel (x, y) sees what colour pixel (x, y) sees,
  /// and depth_intrinsics == color_intrinsics.
  bool registered = false;
  /// For unregistered depth: the device's factory depth-to-colour transform when the source
  /// knows the device (p_colour = color_from_depth * p_depth, metres), and where its numbers
  /// come from. A calibration's extrinsics win over it.
  struct Extrinsics {
    Eigen::Matrix4d color_from_depth = Eigen::Matrix4d::Identity();
    std::string source;
  };
  std::optional<Extrinsics> device_extrinsics;
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
