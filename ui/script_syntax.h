#pragma once
/// The viewer's command file as text (docs/viewer.md): its lines, the commands it knows and
/// how many words each takes. No window here: what runs each command is ui/script.cpp.

#include <map>
#include <string>
#include <vector>

namespace lp::ui {

/// One script line: the command and its words.
struct ScriptLine {
  int number = 0;
  std::vector<std::string> words;
};

/// How many arguments a command takes.
struct ScriptSyntax {
  int min_args = 0, max_args = 0;
};

/// Every command the viewer runs, by name.
const std::map<std::string, ScriptSyntax>& ScriptCommands();

/// The command file's lines (comments after '#' and blank lines left out); throws
/// InputError naming the line for an unknown command or a wrong number of arguments.
/// Linear in the text's length.
std::vector<ScriptLine> ParseScript(const std::string& text, const std::string& name);

}  // namespace lp::ui
