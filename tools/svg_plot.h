// A small SVG line-plot writer for benchmark figures: panels side by side, each with series of
// labelled points on a log2 x axis and a linear y axis, optional horizontal target line.
#pragma once
#include <string>
#include <vector>

namespace tvt::cli {

struct PlotPoint {
  double x = 0, y = 0;
  std::string label;  // drawn beside the point
};

struct PlotSeries {
  std::string name;  // legend
  std::vector<PlotPoint> points;
};

struct PlotPanel {
  std::string title;
  std::vector<PlotSeries> series;
};

struct PlotLayout {
  std::string title;
  std::string subtitle;  // a smaller second line (device, date)
  std::string x_label, y_label;
  double y_min = 0, y_max = 1;  // points outside are clamped to the frame (and marked)
  double target_y = -1;         // < y_min: no target line
  std::string target_label;
};

// The figure as SVG text. x must be > 0 (log2 axis from the smallest to the largest x over
// every panel, at least one octave); non-finite values are left out.
std::string svg_plot(const PlotLayout& layout, const std::vector<PlotPanel>& panels);

}  // namespace tvt::cli
