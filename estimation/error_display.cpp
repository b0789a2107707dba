#include "estimation/error_display.h"

#include <algorithm>

#include "common/color.h"

namespace lp {

float WhiteLevel(const View& view) {
  std::vector<float> lum;
  for (std::size_t i = 0; i < view.valid.size(); ++i)
    if (view.valid[i]) {
      const float* p = &view.image.data[3 * i];
      lum.push_back(static_cast<float>(Luminance(p[0], p[1], p[2])));
    }
  if (lum.empty()) return 1;
  const std::size_t k = lum.size() * 99 / 100;
  std::nth_element(lum.begin(), lum.begin() + k, lum.end());
  return std::max(1e-12f, lum[k]);
}

std::vector<float> ErrorImage(const ImageRGB& render, const View& view) {
  std::vector<float> err(render.pixels(), -1.f);
  for (std::size_t i = 0; i < render.pixels() && i < view.valid.size(); ++i)
    if (view.valid[i]) err[i] = PixelError(&render.data[3 * i], &view.image.data[3 * i]);
  return err;
}

}  // namespace lp
