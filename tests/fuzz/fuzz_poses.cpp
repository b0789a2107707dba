// libFuzzer target: trajectory and pose logs (Redwood trajectory.log, joinMap pose.txt, TUM lists and associations).
#include "capture/trajectory.h"
#include "capture/tum_index.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseTrajectoryLog(text, "trajectory.log"); });
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParsePoseTxt(text, "pose.txt"); });
  lp::fuzz::ReturnsOrRefuses([&] { lp::ParseTumAssociations(text, "associations.txt"); });
  lp::fuzz::ReturnsOrRefuses([&] {  // the text as both lists: each depth frame has a partner at its own time
    const auto list = lp::ParseTumList(text, "rgb.txt");
    lp::PairTumLists(list, list);
  });
  return 0;
}
