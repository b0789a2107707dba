// libFuzzer target: the PLY reader. Bad bytes must end in InputError, nothing else.
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/error.h"
#include "scene/mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    lp::Mesh mesh = lp::ParsePly(std::string(reinterpret_cast<const char*>(data), size), "fuzz.ply");
    lp::SanitizeMesh(&mesh, "fuzz.ply");
  } catch (const lp::InputError&) {
  }
  return 0;
}
