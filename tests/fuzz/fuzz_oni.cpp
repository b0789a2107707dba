// libFuzzer target: the .oni structure check (both record layouts of OpenNI2's player).
// Bad bytes must end in InputError, nothing else; playback itself runs in a separate
// process (capture/oni_file.cpp) and is not fuzzed here.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "capture/openni.h"
#include "common/error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    lp::ValidateOniStream(in, size, "fuzz.oni");
  } catch (const lp::InputError&) {
  }
  return 0;
}
