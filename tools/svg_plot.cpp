#include "tools/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace tvt::cli {
namespace {

constexpr const char* k_colours[] = {"#1b6ca8", "#d1495b", "#edae49", "#00798c", "#66a182", "#8d6a9f", "#3d3b30"};
constexpr double k_panel_w = 340, k_panel_h = 260, k_margin_l = 56, k_margin_r = 16, k_margin_t = 64,
                 k_margin_b = 48, k_gap = 44;

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}

std::string whole(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.0f", v);
  return b;
}

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

}  // namespace

std::string svg_plot(const PlotLayout& layout, const std::vector<PlotPanel>& panels) {
  double x_lo = 1e300, x_hi = 0;
  std::vector<std::string> names;  // legend: every series name, first appearance order
  for (const PlotPanel& p : panels)
    for (const PlotSeries& s : p.series) {
      if (std::find(names.begin(), names.end(), s.name) == names.end()) names.push_back(s.name);
      for (const PlotPoint& q : s.points)
        if (std::isfinite(q.x) && q.x > 0) x_lo = std::min(x_lo, q.x), x_hi = std::max(x_hi, q.x);
    }
  if (!(x_lo < 1e300)) x_lo = 1, x_hi = 2;
  const double l_lo = std::floor(std::log2(x_lo)), l_hi = std::max(std::ceil(std::log2(x_hi)), l_lo + 1);
  const double y_lo = layout.y_min, y_hi = std::max(layout.y_max, layout.y_min + 1e-9);
  const size_t n = std::max<size_t>(panels.size(), 1);
  const double width = k_margin_l + double(n) * k_panel_w + double(n - 1) * k_gap + k_margin_r;
  const double height = k_margin_t + k_panel_h + k_margin_b + 22.0 * double((names.size() + 3) / 4);

  std::string o;
  o += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(width) + "\" height=\"" + num(height) +
       "\" viewBox=\"0 0 " + num(width) + " " + num(height) + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o += "<text x=\"" + num(width / 2) + "\" y=\"20\" text-anchor=\"middle\" font-size=\"15\">" + escape(layout.title) + "</text>\n";
  o += "<text x=\"" + num(width / 2) + "\" y=\"36\" text-anchor=\"middle\" font-size=\"11\" fill=\"#555\">" +
       escape(layout.subtitle) + "</text>\n";
  for (size_t pi = 0; pi < panels.size(); ++pi) {
    const PlotPanel& p = panels[pi];
    const double x0 = k_margin_l + double(pi) * (k_panel_w + k_gap), y0 = k_margin_t;
    auto px = [&](double x) { return x0 + (std::log2(x) - l_lo) / (l_hi - l_lo) * k_panel_w; };
    auto py = [&](double y) { return y0 + (1.0 - (std::clamp(y, y_lo, y_hi) - y_lo) / (y_hi - y_lo)) * k_panel_h; };
    o += "<g class=\"panel\">\n<text x=\"" + num(x0 + k_panel_w / 2) + "\" y=\"" + num(y0 - 10) +
         "\" text-anchor=\"middle\" font-size=\"13\">" + escape(p.title) + "</text>\n";
    o += "<rect x=\"" + num(x0) + "\" y=\"" + num(y0) + "\" width=\"" + num(k_panel_w) + "\" height=\"" + num(k_panel_h) +
         "\" fill=\"none\" stroke=\"#444\"/>\n";
    const double label_step = std::max(1.0, std::ceil((l_hi - l_lo) / 6.0));  // at most ~7 labels a panel
    for (double l = l_lo; l <= l_hi; l += 1.0) {  // x grid: powers of two
      const double x = px(std::exp2(l));
      o += "<line x1=\"" + num(x) + "\" y1=\"" + num(y0) + "\" x2=\"" + num(x) + "\" y2=\"" + num(y0 + k_panel_h) +
           "\" stroke=\"#ddd\"/>\n";
      if (std::fmod(l - l_lo, label_step) == 0.0)
        o += "<text x=\"" + num(x) + "\" y=\"" + num(y0 + k_panel_h + 16) + "\" text-anchor=\"middle\">" +
             whole(std::exp2(l)) + "×</text>\n";
    }
    const double y_step = (y_hi - y_lo) > 30 ? 10 : 5;
    for (double y = std::ceil(y_lo / y_step) * y_step; y <= y_hi; y += y_step) {
      o += "<line x1=\"" + num(x0) + "\" y1=\"" + num(py(y)) + "\" x2=\"" + num(x0 + k_panel_w) + "\" y2=\"" + num(py(y)) +
           "\" stroke=\"#eee\"/>\n";
      if (pi == 0)
        o += "<text x=\"" + num(x0 - 6) + "\" y=\"" + num(py(y) + 4) + "\" text-anchor=\"end\">" + whole(y) +
             "</text>\n";
    }
    if (layout.target_y >= y_lo && layout.target_y <= y_hi)
      o += "<line x1=\"" + num(x0) + "\" y1=\"" + num(py(layout.target_y)) + "\" x2=\"" + num(x0 + k_panel_w) + "\" y2=\"" +
           num(py(layout.target_y)) + "\" stroke=\"#2a9d3a\" stroke-dasharray=\"6 4\"/>\n<text x=\"" + num(x0 + k_panel_w - 4) +
           "\" y=\"" + num(py(layout.target_y) - 4) + "\" text-anchor=\"end\" fill=\"#2a9d3a\">" + escape(layout.target_label) +
           "</text>\n";
    for (const PlotSeries& s : p.series) {
      const size_t ci = size_t(std::find(names.begin(), names.end(), s.name) - names.begin()) % std::size(k_colours);
      std::string pts;
      for (const PlotPoint& q : s.points)
        if (std::isfinite(q.x) && q.x > 0 && std::isfinite(q.y)) pts += num(px(q.x)) + "," + num(py(q.y)) + " ";
      o += "<polyline class=\"series\" data-name=\"" + escape(s.name) + "\" points=\"" + pts + "\" fill=\"none\" stroke=\"" +
           k_colours[ci] + "\" stroke-width=\"2\"/>\n";
      for (const PlotPoint& q : s.points) {
        if (!(std::isfinite(q.x) && q.x > 0 && std::isfinite(q.y))) continue;
        const bool clamped = q.y < y_lo || q.y > y_hi;
        o += "<circle cx=\"" + num(px(q.x)) + "\" cy=\"" + num(py(q.y)) + "\" r=\"3.5\" fill=\"" +
             (clamped ? std::string("white") : std::string(k_colours[ci])) + "\" stroke=\"" + k_colours[ci] + "\"/>\n";
        if (!q.label.empty())
          o += "<text x=\"" + num(px(q.x) + 5) + "\" y=\"" + num(py(q.y) - 5) + "\" font-size=\"10\" fill=\"" + k_colours[ci] +
               "\">" + escape(q.label) + "</text>\n";
      }
    }
    o += "</g>\n";
  }
  const double axis_y = k_margin_t + k_panel_h + 36;
  o += "<text x=\"" + num(width / 2) + "\" y=\"" + num(axis_y) + "\" text-anchor=\"middle\">" + escape(layout.x_label) + "</text>\n";
  o += "<text x=\"14\" y=\"" + num(k_margin_t + k_panel_h / 2) + "\" text-anchor=\"middle\" transform=\"rotate(-90 14 " +
       num(k_margin_t + k_panel_h / 2) + ")\">" + escape(layout.y_label) + "</text>\n";
  for (size_t i = 0; i < names.size(); ++i) {
    const double lx = k_margin_l + double(i % 4) * 170, ly = axis_y + 20 + 22.0 * double(i / 4);
    o += "<line x1=\"" + num(lx) + "\" y1=\"" + num(ly - 4) + "\" x2=\"" + num(lx + 24) + "\" y2=\"" + num(ly - 4) +
         "\" stroke=\"" + k_colours[i % std::size(k_colours)] + "\" stroke-width=\"2\"/>\n<text x=\"" + num(lx + 30) + "\" y=\"" +
         num(ly) + "\">" + escape(names[i]) + "</text>\n";
  }
  o += "</svg>\n";
  return o;
}

}  // namespace tvt::cli
