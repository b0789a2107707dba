#pragma once
/// How photometric errors are shown, the same everywhere: error_view*.png (estimate),
/// the viewer's error shading and its keyframe panel, the per-vertex error of the lit
/// shading (estimation/vertex_radiance.h).
#include <cmath>
#include <vector>

#include "common/image.h"
#include "scene/scene_bundle.h"

namespace lp {

/// A view's white level: the 99th-percentile luminance of its valid pixels (1 if none).
/// Renders are shown with it mapped to white, and photometric errors as a fraction of it.
float WhiteLevel(const View& view);

/// Errors are shown in viridis from 0 to this fraction of the white level, in the same
/// way everywhere: error_view*.png, the viewer's error shading and its keyframe panel.
constexpr float kErrorDisplayFraction = 0.25f;

/// The error shown for one pixel: the RMS over the three channels of rendered - observed.
inline float PixelError(const float* rendered, const float* observed) {
  float s = 0;
  for (int c = 0; c < 3; ++c) s += (rendered[c] - observed[c]) * (rendered[c] - observed[c]);
  return std::sqrt(s / 3);
}

/// PixelError of `render` against the view per pixel; -1 where the view's pixel is not
/// valid (Heatmap() shows those black).
std::vector<float> ErrorImage(const ImageRGB& render, const View& view);

}  // namespace lp
