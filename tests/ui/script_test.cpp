// The viewer's command file as text (no window): what ParseScript takes and refuses.
#include <gtest/gtest.h>

#include "common/error.h"
#include "ui/viewer_internal.h"

namespace lp::ui {
namespace {

std::string ErrorOf(const std::string& text) {
  try {
    ParseScript(text, "s.txt");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Script, LinesCommentsAndArgumentCounts) {
  const auto lines = ParseScript("# a comment\n\nwait-open 60  # trailing\norbit 10 5\r\nquit\n", "s.txt");
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0].number, 3);
  EXPECT_EQ(lines[0].words, (std::vector<std::string>{"wait-open", "60"}));
  EXPECT_EQ(lines[1].words, (std::vector<std::string>{"orbit", "10", "5"}));
  EXPECT_EQ(lines[2].number, 5);
  EXPECT_NE(ErrorOf("quit\nfly 3\n").find("s.txt: line 2: unknown command fly"), std::string::npos);
  EXPECT_NE(ErrorOf("orbit 10\n").find("line 1: wrong number of arguments for orbit"), std::string::npos);
  EXPECT_NE(ErrorOf("quit now\n").find("wrong number of arguments"), std::string::npos);
  // A huge unknown word is cut in the message, not echoed whole.
  EXPECT_LT(ErrorOf(std::string(100000, 'x')).size(), 200u);
}

TEST(Script, EveryCommandHasAHandler) {
  EXPECT_TRUE(UnhandledScriptCommands().empty());
  EXPECT_GE(ScriptCommands().size(), 29u);
}

}  // namespace
}  // namespace lp::ui
