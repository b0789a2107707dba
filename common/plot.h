#pragma once
/// Line plots written as PNG (OpenCV drawing): panels in a grid, log or linear axes,
/// one colour per series label shared by every panel, and one legend for the figure.
/// Enough for convergence and error-against-time plots; no other plotting library.
#include <filesystem>
#include <string>
#include <vector>

namespace lp {

struct PlotSeries {
  std::string label;          ///< legend entry; series with the same label share a colour
  std::vector<double> x, y;   ///< points (non-finite ones, and non-positive on log axes, are skipped)
  bool lines = true;          ///< join consecutive points
  bool markers = true;        ///< draw a marker at each point (only the last one if false and many points)
  int marker_radius = 3;      ///< in pixels
};

struct PlotPanel {
  std::string title;
  std::string x_label, y_label;
  bool log_x = true, log_y = true;
  std::vector<PlotSeries> series;
  /// Horizontal reference lines (e.g. a target error), drawn dashed grey.
  std::vector<double> reference_y;
};

/// Renders `panels` in a grid of `columns` under `title`, with a shared legend, and
/// writes the PNG atomically. Throws on an empty panel list.
void WritePlotPng(const std::filesystem::path& path, const std::string& title, const std::vector<PlotPanel>& panels,
                  int columns);

/// The PNG bytes of the same figure (for tests).
std::string RenderPlotPng(const std::string& title, const std::vector<PlotPanel>& panels, int columns);

}  // namespace lp
