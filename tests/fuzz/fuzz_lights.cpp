// libFuzzer target: lights.json (render --lights, the exports).
#include "estimation/lights_file.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseLightsJson(text, "lights.json"); });
  return 0;
}
