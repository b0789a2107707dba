// libFuzzer target: truth.json (synthetic and Cycles bundles).
#include "estimation/truth.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseTruthLights(text, "truth.json"); });
  return 0;
}
