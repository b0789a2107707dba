// libFuzzer target: the small JSON files beside recordings and frames: the .oni side file
// (FILE.oni.json) and a frame directory's intrinsics.json / Open3D camera JSON.
#include "capture/frame_source.h"
#include "capture/openni.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseOniSideFile(text, "fuzz.oni.json"); });
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseDirectoryIntrinsics(text, "intrinsics.json"); });
  return 0;
}
