// libFuzzer target: the viewer's command file (view --script; each command's arguments are checked as it runs).
#include "ui/script_syntax.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = lp::fuzz::Text(data, size);
  lp::fuzz::ReturnsOrRefuses([&] { lp::ui::ParseScript(text, "script.txt"); });
  return 0;
}
