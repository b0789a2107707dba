// The command file's syntax: which commands exist and how many words each takes.
#include "ui/script_syntax.h"

#include <sstream>

#include "common/error.h"

namespace lp::ui {

const std::map<std::string, ScriptSyntax>& ScriptCommands() {
  static const std::map<std::string, ScriptSyntax> commands = {
      {"open", {1, 1}},
      {"wait-open", {0, 1}},
      {"play", {0, 0}},
      {"pause", {0, 0}},
      {"seek", {1, 1}},
      {"speed", {1, 1}},
      {"reconstruct", {1, 1}},
      {"wait-end", {0, 1}},
      {"wait-frames", {1, 2}},
      {"record", {2, 2}},
      {"stop-recording", {0, 0}},
      {"wait-record", {0, 1}},
      {"estimate", {0, 20}},
      {"cancel", {0, 0}},
      {"live", {1, 20}},
      {"wait-live", {1, 2}},
      {"wait-map", {0, 1}},
      {"wait-first", {0, 1}},
      {"wait-estimate", {0, 1}},
      {"expect-estimate", {1, 1}},
      {"wait-lit", {1, 2}},
      {"wait-render", {1, 2}},
      {"export", {1, 2}},
      {"wait-export", {0, 1}},
      {"shading", {1, 1}},
      {"keyframe", {1, 1}},
      {"orbit", {2, 2}},
      {"frames", {1, 1}},
      {"sleep", {1, 1}},
      {"screenshot", {1, 1}},
      {"bench-frames", {1, 2}},
      {"state", {1, 1}},
      {"quit", {0, 0}},
      {"close", {0, 0}},
  };
  return commands;
}

std::vector<ScriptLine> ParseScript(const std::string& text, const std::string& path) {
  std::vector<ScriptLine> lines;
  std::istringstream in(text);
  std::string row;
  int number = 0;
  while (std::getline(in, row)) {
    ++number;
    const std::size_t hash = row.find('#');
    if (hash != std::string::npos) row.resize(hash);
    std::istringstream words(row);
    ScriptLine line;
    line.number = number;
    for (std::string w; words >> w;) line.words.push_back(w);
    if (line.words.empty()) continue;
    const auto it = ScriptCommands().find(line.words[0]);
    if (it == ScriptCommands().end())
      throw InputError(path, "line " + std::to_string(number) + ": unknown command " + line.words[0].substr(0, 64));
    const int args = static_cast<int>(line.words.size()) - 1;
    if (args < it->second.min_args || args > it->second.max_args)
      throw InputError(path, "line " + std::to_string(number) + ": wrong number of arguments for " + line.words[0]);
    lines.push_back(std::move(line));
  }
  return lines;
}

}  // namespace lp::ui
