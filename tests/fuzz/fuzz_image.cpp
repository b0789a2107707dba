// libFuzzer target: the image and mask decoders (PNG, OpenEXR, PFM, Radiance HDR through OpenCV).
#include "common/image_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::DecodeImageLinear(text, "fuzz-image"); });
  lp::fuzz::ReturnsOrRefuses([&] { lp::DecodeMask(text, "fuzz-mask"); });
  return 0;
}
