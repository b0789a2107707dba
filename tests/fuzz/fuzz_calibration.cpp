// libFuzzer target: the calibration file (calibrate's output, --calibration) and an
// intrinsics file (--intrinsics: its camera section alone).
#include "calibration/calibration.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseCalibration(text, "calibration.json"); });
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseIntrinsics(text, "intrinsics.json"); });
  return 0;
}
