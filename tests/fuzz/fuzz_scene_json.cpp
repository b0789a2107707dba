// libFuzzer target: the scene.json reader.
#include "scene/scene_bundle.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseSceneJson(text, "scene.json"); });
  return 0;
}
