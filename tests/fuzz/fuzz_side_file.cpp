// libFuzzer target: the .oni side file (FILE.oni.json).
#include "capture/openni.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseOniSideFile(text, "fuzz.oni.json"); });
  return 0;
}
