// libFuzzer target: the PLY reader (and the mesh checks after it).
#include "scene/mesh.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] {
    lp::Mesh mesh = lp::ParsePly(text, "fuzz.ply");
    lp::SanitizeMesh(&mesh, "fuzz.ply");
  });
  return 0;
}
