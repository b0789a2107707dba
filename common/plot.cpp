#include "common/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/atomic_file.h"
#include "common/error.h"

namespace lp {
namespace {

constexpr int kPanelW = 440, kPanelH = 320;
constexpr int kLeft = 64, kRight = 14, kTop = 30, kBottom = 44;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

cv::Scalar Colour(int i) {
  // Tableau 10 (BGR), then darker variants.
  static const int rgb[10][3] = {{31, 119, 180}, {255, 127, 14}, {44, 160, 44},  {214, 39, 40},  {148, 103, 189},
                                 {140, 86, 75},  {227, 119, 194}, {127, 127, 127}, {188, 189, 34}, {23, 190, 207}};
  const int* c = rgb[i % 10];
  const double k = (i / 10) % 2 ? 0.6 : 1.0;
  return cv::Scalar(c[2] * k, c[1] * k, c[0] * k);
}

struct Axis {
  bool log = true;
  double lo = 0, hi = 1;  // in axis units (log10 when log)
  double Map(double v) const { return log ? std::log10(v) : v; }
  bool Usable(double v) const { return std::isfinite(v) && (!log || v > 0); }
};

/// Fits an axis to values; pads a degenerate range.
Axis FitAxis(const std::vector<double>& values, bool log) {
  Axis a;
  a.log = log;
  double lo = 1e300, hi = -1e300;
  for (double v : values)
    if (a.Usable(v)) {
      lo = std::min(lo, a.Map(v));
      hi = std::max(hi, a.Map(v));
    }
  if (lo > hi) {
    lo = log ? 0 : 0;
    hi = 1;
  }
  if (hi - lo < 1e-9) {
    const double pad = log ? 0.5 : std::max(1e-9, std::abs(lo) * 0.1 + 0.5);
    lo -= pad;
    hi += pad;
  }
  const double pad = 0.04 * (hi - lo);
  a.lo = lo - pad;
  a.hi = hi + pad;
  return a;
}

std::string TickLabel(double v) {
  char buf[32];
  const double a = std::abs(v);
  if (v == 0)
    return "0";
  else if (a >= 1e4 || a < 1e-3)
    std::snprintf(buf, sizeof buf, "%.0e", v);
  else
    std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

/// Tick values (data units) for an axis.
std::vector<double> Ticks(const Axis& a) {
  std::vector<double> t;
  if (a.log && a.hi - a.lo < 1) {  // less than a decade: evenly spaced round values inside
    Axis lin;
    lin.log = false;
    lin.lo = std::pow(10.0, a.lo);
    lin.hi = std::pow(10.0, a.hi);
    for (double v : Ticks(lin))
      if (v > 0) t.push_back(v);
  } else if (a.log) {
    const int d0 = static_cast<int>(std::floor(a.lo)), d1 = static_cast<int>(std::ceil(a.hi));
    const bool fine = a.hi - a.lo <= 3;
    for (int d = d0; d <= d1; ++d)
      for (double m : fine ? std::vector<double>{1, 2, 5} : std::vector<double>{1}) {
        const double v = m * std::pow(10.0, d);
        if (std::log10(v) >= a.lo && std::log10(v) <= a.hi) t.push_back(v);
      }
    if (t.size() > 9) {  // many decades: every other one
      std::vector<double> s;
      for (std::size_t i = 0; i < t.size(); i += 2) s.push_back(t[i]);
      t = s;
    }
  } else {
    const double span = a.hi - a.lo;
    const double raw = span / 5, mag = std::pow(10.0, std::floor(std::log10(raw)));
    double step = mag;
    for (double m : {1.0, 2.0, 5.0, 10.0})
      if (m * mag >= raw) {
        step = m * mag;
        break;
      }
    for (double k = std::ceil(a.lo / step); k * step <= a.hi * (1 + 1e-12) && t.size() < 50; ++k) t.push_back(k * step);
  }
  return t;
}

void DashedLine(cv::Mat& m, cv::Point a, cv::Point b, const cv::Scalar& c) {
  const double len = std::hypot(b.x - a.x, b.y - a.y);
  for (double s = 0; s < len; s += 8) {
    const double e = std::min(len, s + 4);
    cv::line(m, a + (b - a) * (s / len), a + (b - a) * (e / len), c, 1, cv::LINE_AA);
  }
}

void DrawPanel(cv::Mat& m, int ox, int oy, const PlotPanel& p, const std::map<std::string, int>& colour_of) {
  std::vector<double> xs, ys;
  for (const PlotSeries& s : p.series) {
    xs.insert(xs.end(), s.x.begin(), s.x.end());
    ys.insert(ys.end(), s.y.begin(), s.y.end());
  }
  ys.insert(ys.end(), p.reference_y.begin(), p.reference_y.end());
  const Axis ax = FitAxis(xs, p.log_x), ay = FitAxis(ys, p.log_y);
  const int x0 = ox + kLeft, x1 = ox + kPanelW - kRight, y0 = oy + kTop, y1 = oy + kPanelH - kBottom;
  auto px = [&](double v) { return x0 + (ax.Map(v) - ax.lo) / (ax.hi - ax.lo) * (x1 - x0); };
  auto py = [&](double v) { return y1 - (ay.Map(v) - ay.lo) / (ay.hi - ay.lo) * (y1 - y0); };
  const cv::Scalar black(0, 0, 0), grid(225, 225, 225), grey(120, 120, 120);
  for (double t : Ticks(ax)) {
    const int x = static_cast<int>(std::lround(px(t)));
    cv::line(m, {x, y0}, {x, y1}, grid, 1);
    const std::string s = TickLabel(t);
    int base = 0;
    const cv::Size sz = cv::getTextSize(s, kFont, 0.38, 1, &base);
    cv::putText(m, s, {x - sz.width / 2, y1 + 15}, kFont, 0.38, black, 1, cv::LINE_AA);
  }
  for (double t : Ticks(ay)) {
    const int y = static_cast<int>(std::lround(py(t)));
    cv::line(m, {x0, y}, {x1, y}, grid, 1);
    const std::string s = TickLabel(t);
    int base = 0;
    const cv::Size sz = cv::getTextSize(s, kFont, 0.38, 1, &base);
    cv::putText(m, s, {x0 - sz.width - 5, y + 4}, kFont, 0.38, black, 1, cv::LINE_AA);
  }
  cv::rectangle(m, {x0, y0}, {x1, y1}, black, 1);
  cv::putText(m, p.title, {x0, oy + 18}, kFont, 0.48, black, 1, cv::LINE_AA);
  {
    int base = 0;
    const cv::Size sz = cv::getTextSize(p.x_label, kFont, 0.4, 1, &base);
    cv::putText(m, p.x_label, {(x0 + x1 - sz.width) / 2, y1 + 34}, kFont, 0.4, black, 1, cv::LINE_AA);
  }
  if (!p.y_label.empty()) {  // rotated: drawn into a strip, then turned
    int base = 0;
    const cv::Size sz = cv::getTextSize(p.y_label, kFont, 0.4, 1, &base);
    cv::Mat strip(sz.height + base + 4, sz.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::putText(strip, p.y_label, {2, sz.height + 1}, kFont, 0.4, black, 1, cv::LINE_AA);
    cv::Mat turned;
    cv::rotate(strip, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int ty = std::max(oy, (y0 + y1 - turned.rows) / 2);
    const int h = std::min(turned.rows, m.rows - ty);
    if (h > 0) turned(cv::Rect(0, 0, turned.cols, h)).copyTo(m(cv::Rect(ox + 2, ty, turned.cols, h)));
  }
  for (double r : p.reference_y)
    if (ay.Usable(r)) {
      const int y = static_cast<int>(std::lround(py(r)));
      DashedLine(m, {x0, y}, {x1, y}, grey);
    }
  cv::Mat clip = m(cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1));
  const cv::Point off(x0, y0);
  bool any = false;
  for (const PlotSeries& s : p.series) {
    const auto it = colour_of.find(s.label);
    const cv::Scalar c = Colour(it == colour_of.end() ? 0 : it->second);
    std::vector<cv::Point> pts;
    for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
      if (ax.Usable(s.x[i]) && ay.Usable(s.y[i]))
        pts.emplace_back(static_cast<int>(std::lround(px(s.x[i]))) - off.x,
                         static_cast<int>(std::lround(py(s.y[i]))) - off.y);
    any = any || !pts.empty();
    if (s.lines)
      for (std::size_t i = 1; i < pts.size(); ++i) cv::line(clip, pts[i - 1], pts[i], c, 2, cv::LINE_AA);
    const bool all = s.markers || pts.size() <= 1;
    for (std::size_t i = 0; i < pts.size(); ++i)
      if (all || i + 1 == pts.size()) cv::circle(clip, pts[i], s.marker_radius, c, cv::FILLED, cv::LINE_AA);
  }
  if (!any) cv::putText(m, "no data", {(x0 + x1) / 2 - 25, (y0 + y1) / 2}, kFont, 0.45, grey, 1, cv::LINE_AA);
}

}  // namespace

std::string RenderPlotPng(const std::string& title, const std::vector<PlotPanel>& panels, int columns) {
  LP_CHECK(!panels.empty(), "a figure needs at least one panel");
  columns = std::max(1, std::min<int>(columns, static_cast<int>(panels.size())));
  const int rows = (static_cast<int>(panels.size()) + columns - 1) / columns;
  std::map<std::string, int> colour_of;
  std::vector<std::string> labels;
  for (const PlotPanel& p : panels)
    for (const PlotSeries& s : p.series)
      if (!s.label.empty() && colour_of.emplace(s.label, static_cast<int>(colour_of.size())).second)
        labels.push_back(s.label);
  // Legend: entries flowed into lines across the figure width.
  const int width = columns * kPanelW;
  std::vector<std::vector<std::string>> legend_lines(1);
  int used = 10;
  for (const std::string& l : labels) {
    int base = 0;
    const int w = cv::getTextSize(l, kFont, 0.42, 1, &base).width + 40;
    if (used + w > width - 10 && !legend_lines.back().empty()) {
      legend_lines.emplace_back();
      used = 10;
    }
    legend_lines.back().push_back(l);
    used += w;
  }
  const int top = 34, legend_h = labels.empty() ? 0 : 8 + 20 * static_cast<int>(legend_lines.size());
  cv::Mat m(top + rows * kPanelH + legend_h, width, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::putText(m, title, {10, 23}, kFont, 0.6, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  for (std::size_t i = 0; i < panels.size(); ++i)
    DrawPanel(m, static_cast<int>(i % columns) * kPanelW, top + static_cast<int>(i / columns) * kPanelH, panels[i],
              colour_of);
  int y = top + rows * kPanelH + 14;
  for (const auto& line : legend_lines) {
    int x = 10;
    for (const std::string& l : line) {
      const cv::Scalar c = Colour(colour_of.at(l));
      cv::line(m, {x, y - 4}, {x + 22, y - 4}, c, 2, cv::LINE_AA);
      cv::circle(m, {x + 11, y - 4}, 3, c, cv::FILLED, cv::LINE_AA);
      cv::putText(m, l, {x + 28, y}, kFont, 0.42, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      int base = 0;
      x += cv::getTextSize(l, kFont, 0.42, 1, &base).width + 40;
    }
    y += 20;
  }
  std::vector<unsigned char> png;
  LP_CHECK(cv::imencode(".png", m, png), "PNG encoding failed");
  return std::string(png.begin(), png.end());
}

void WritePlotPng(const std::filesystem::path& path, const std::string& title, const std::vector<PlotPanel>& panels,
                  int columns) {
  WriteTextAtomically(path, RenderPlotPng(title, panels, columns));
}

}  // namespace lp
