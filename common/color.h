#pragma once
/// sRGB transfer function (IEC 61966-2-1); colour is sRGB-encoded only at the edges.
#include <algorithm>
#include <cmath>

namespace lp {

/// sRGB-encoded value in [0, 1] -> linear.
inline float SrgbToLinear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

/// Linear value -> sRGB-encoded in [0, 1] (clamped).
inline float LinearToSrgb(float v) {
  v = std::clamp(v, 0.f, 1.f);
  return v <= 0.0031308f ? v * 12.92f : 1.055f * std::pow(v, 1.f / 2.4f) - 0.055f;
}

/// Rec. 709 luminance of linear RGB.
inline double Luminance(double r, double g, double b) { return 0.2126 * r + 0.7152 * g + 0.0722 * b; }

}  // namespace lp
