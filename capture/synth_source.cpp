#include "capture/synth_source.h"

#include <cmath>

#include "common/image_io.h"

namespace lp {

std::vector<RgbdFrame> ToRgbdFrames(const std::vector<SynthFrame>& frames) {
  std::vector<RgbdFrame> out;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const SynthFrame& s = frames[k];
    RgbdFrame f;
    f.index = static_cast<std::int64_t>(k);
    f.color = EncodeSrgb8(s.color);
    f.depth = {s.color.width, s.color.height, std::vector<std::uint16_t>(s.depth.size())};
    for (std::size_t i = 0; i < s.depth.size(); ++i)
      f.depth.data[i] =
          s.depth[i] > 0 && s.depth[i] < 65.535f ? static_cast<std::uint16_t>(std::lround(s.depth[i] * 1000)) : 0;
    const Camera& c = s.camera;
    f.color_intrinsics = f.depth_intrinsics = c.Intrinsics();
    f.registered = true;
    f.world_from_camera = c.world_from_camera;
    f.depth_timestamp = f.color_timestamp = k / 30.0;
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace lp
