#pragma once
/// The index files of a TUM RGB-D directory: `rgb.txt` / `depth.txt` ("timestamp path"
/// lines, '#' comments) paired by time, or a ready `associations.txt`
/// ("t_colour colour_path t_depth depth_path"). Paths are as written (relative to the
/// directory). Parsers take the text and a name for errors, and throw InputError.

#include <string>
#include <vector>

namespace lp {

/// A colour and a depth frame that belong together.
struct TumFrame {
  double color_time = 0;
  std::string color;
  double depth_time = 0;
  std::string depth;
};

/// One line of rgb.txt or depth.txt.
struct TumListEntry {
  double time = 0;
  std::string path;
};

/// TUM's associate.py pairs frames closer than 20 ms.
inline constexpr double kTumMaxTimeDifference = 0.02;

std::vector<TumFrame> ParseTumAssociations(const std::string& text, const std::string& name);
std::vector<TumListEntry> ParseTumList(const std::string& text, const std::string& name);

/// Each depth frame with the colour frame nearest in time (the first listed on a tie),
/// when that is under kTumMaxTimeDifference; depth frames without one are left out.
/// n log n in the list lengths.
std::vector<TumFrame> PairTumLists(const std::vector<TumListEntry>& rgb, const std::vector<TumListEntry>& depth);

}  // namespace lp
