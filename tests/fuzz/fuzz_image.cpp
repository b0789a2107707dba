// libFuzzer target: the image and mask decoders (PNG, OpenEXR, PFM, Radiance HDR through
// OpenCV). Bad bytes must end in InputError, nothing else.
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/error.h"
#include "common/image_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    lp::DecodeImageLinear(bytes, "fuzz-image");
  } catch (const lp::InputError&) {
  }
  try {
    lp::DecodeMask(bytes, "fuzz-mask");
  } catch (const lp::InputError&) {
  }
  return 0;
}
