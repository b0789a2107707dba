#pragma once
/// Linear float images, the only image type inside the pipeline.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace lp {

/// Linear RGB, row-major, interleaved (r, g, b) per pixel; pixel (x, y) with
/// the top-left pixel at (0, 0).
struct ImageRGB {
  int width = 0;
  int height = 0;
  std::vector<float> data;  ///< 3 * width * height

  ImageRGB() = default;
  ImageRGB(int w, int h, float fill = 0.f)
      : width(w), height(h), data(static_cast<std::size_t>(3) * w * h, fill) {}
  std::size_t pixels() const { return static_cast<std::size_t>(width) * height; }
  float* at(int x, int y) { return &data[3 * (static_cast<std::size_t>(y) * width + x)]; }
  const float* at(int x, int y) const { return &data[3 * (static_cast<std::size_t>(y) * width + x)]; }
};

/// 8-bit RGB as a camera or a file delivers it (sRGB-encoded), row-major, interleaved.
/// Only at the edges of the pipeline: calibration turns it into linear ImageRGB.
struct ImageRgb8 {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> data;  ///< 3 * width * height
  std::size_t pixels() const { return static_cast<std::size_t>(width) * height; }
};

/// Depth in millimetres, row-major; 0 = no measurement.
struct DepthImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint16_t> data;  ///< width * height
  std::size_t pixels() const { return static_cast<std::size_t>(width) * height; }
};

/// Single-channel 8-bit mask; non-zero = use the pixel.
struct Mask {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> data;
};

}  // namespace lp
