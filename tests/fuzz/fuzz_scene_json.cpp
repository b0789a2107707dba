// libFuzzer target: the scene.json reader. Bad text must end in InputError, nothing else.
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/error.h"
#include "scene/scene_bundle.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    lp::ParseSceneJson(std::string(reinterpret_cast<const char*>(data), size), "scene.json");
  } catch (const lp::InputError&) {
  }
  return 0;
}
