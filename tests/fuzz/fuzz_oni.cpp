// libFuzzer target: the .oni structure check (both record layouts of OpenNI2's player).
// Playback itself runs in a separate process (capture/oni_file.cpp) and is not fuzzed here.
#include <sstream>

#include "capture/openni.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(lp::fuzz::Text(data, size));
  lp::fuzz::ReturnsOrRefuses([&] { lp::ValidateOniStream(in, size, "fuzz.oni"); });
  return 0;
}
