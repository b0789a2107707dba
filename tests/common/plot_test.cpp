// The PNG plots of the reports: what is drawn is really there, and bad values do not crash.
#include <cmath>

#include <gtest/gtest.h>

#include "common/image_io.h"
#include "common/plot.h"

namespace lp {
namespace {

/// Pixels whose channels differ (the series colours; axes, text and grid are grey).
int ColouredPixels(const ImageRGB& img) {
  int n = 0;
  for (std::size_t i = 0; i < img.pixels(); ++i) {
    const float* p = &img.data[3 * i];
    n += std::abs(p[0] - p[1]) > 0.05f || std::abs(p[1] - p[2]) > 0.05f;
  }
  return n;
}

TEST(Plot, SeriesAreDrawnAndTheGridHasTheRightSize) {
  PlotPanel a;
  a.title = "log-log";
  a.series.push_back({"fast", {0.1, 1, 10}, {1, 0.1, 0.01}});
  PlotPanel b = a;
  b.log_x = b.log_y = false;
  b.title = "linear";
  PlotPanel empty;
  empty.title = "nothing";
  const ImageRGB img = DecodeImageLinear(RenderPlotPng("t", {a, b, empty}, 2), "plot.png");
  EXPECT_EQ(img.width, 2 * 440);
  EXPECT_GT(img.height, 2 * 320);
  EXPECT_GT(ColouredPixels(img), 200);
  // The same figure with no series has no colour at all.
  const ImageRGB blank = DecodeImageLinear(RenderPlotPng("t", {empty, empty}, 2), "blank.png");
  EXPECT_EQ(ColouredPixels(blank), 0);
}

TEST(Plot, NonFiniteAndNonPositiveValuesOnLogAxesAreSkipped) {
  PlotPanel p;
  p.series.push_back({"bad", {0, -1, NAN, INFINITY, 1e-300, 1e300}, {1, 2, 3, NAN, -5, 0}});
  p.series.push_back({"one point", {2}, {3}});
  p.reference_y = {NAN, -1, 2};
  const std::string png = RenderPlotPng("odd values", {p}, 3);
  EXPECT_GT(ColouredPixels(DecodeImageLinear(png, "odd.png")), 0);
}

}  // namespace
}  // namespace lp
