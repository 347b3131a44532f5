#include "sim/report/mrc_chart.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim/report/html_escape.h"
#include "sim/report/svg_chart.h"

namespace vtsim {

namespace {

// The sweep report's palette (sim/report/sweep_report.cpp): Tableau 10, distinguishable in print.
const char* const kMrcPalette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                   "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
constexpr double kMrcW = 640, kMrcL = 56, kMrcR = 16, kMrcT = 44, kMrcPH = 260;
const char* const kMrcFont = "font-family=\"system-ui,sans-serif\" font-size=\"11\" fill=\"#555\"";

// A step of 1, 2 or 5 times a power of ten giving 4-8 ticks over [0, hi].
double mrc_tick_step(double hi) {
  if (!(hi > 0)) return 1;
  const double raw = hi / 5, mag = std::pow(10.0, std::floor(std::log10(raw))), n = raw / mag;
  return (n <= 1 ? 1 : n <= 2 ? 2 : n <= 5 ? 5 : 10) * mag;
}

std::string mrc_num(double v) {
  if (v == std::floor(v) && std::fabs(v) < 1e15) return fmt::format("{:.0f}", v);
  return fmt::format("{:.3g}", v);
}

}  // namespace

std::string mrc_chart_svg(const std::vector<MrcChartSeries>& series, const std::string& title) {
  for (const auto& s : series)
    if (s.curve.unit != series.front().curve.unit) throw std::invalid_argument("mrc_chart_svg: curves of different units");
  const bool bytes = !series.empty() && series.front().curve.unit == MrcUnit::kBytes;
  const double scale = bytes ? 1.0 / 1048576.0 : 1.0;  // x in MiB or pages
  double xmax = 0;
  for (const auto& s : series)
    for (std::uint64_t c : s.curve.capacity) xmax = std::max(xmax, static_cast<double>(c) * scale);
  const double step = mrc_tick_step(xmax);
  const double xhi = std::max(step, std::ceil(xmax / step - 1e-9) * step);
  const double pw = kMrcW - kMrcL - kMrcR;
  auto X = [&](double v) { return kMrcL + pw * v / xhi; };
  auto Y = [&](double r) { return kMrcT + kMrcPH * (1.0 - r); };
  const double legend_y = kMrcT + kMrcPH + 44;
  const double h = legend_y + 16.0 * static_cast<double>(std::max<std::size_t>(series.size(), 1)) + 4;

  std::string o = chart_svg_open(kMrcW, h, title) + "<rect width=\"100%\" height=\"100%\" fill=\"#fcfcfc\" stroke=\"#e5e5e5\"/>\n";
  o += fmt::format("<text x=\"8\" y=\"18\" font-family=\"system-ui,sans-serif\" font-size=\"13\" font-weight=\"600\" "
                   "fill=\"#222\">{}</text>\n",
                   html_escape(title));
  o += fmt::format("<text x=\"8\" y=\"34\" {}>LRU miss ratio against cache size; a dot marks each curve's knee "
                   "(Kneedle)</text>\n",
                   kMrcFont);
  for (int k = 0; k <= 4; ++k) {
    const double r = k / 4.0;
    o += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"#e8e8e8\"/>\n", kMrcL,
                     kMrcL + pw, Y(r), Y(r));
    o += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"end\" {}>{}</text>\n", kMrcL - 5, Y(r) + 4, kMrcFont,
                     mrc_num(r));
  }
  for (double v = 0; v <= xhi + step * 1e-6; v += step) {
    o += fmt::format("<line x1=\"{0:.1f}\" x2=\"{0:.1f}\" y1=\"{1:.1f}\" y2=\"{2:.1f}\" stroke=\"#e8e8e8\"/>\n", X(v), kMrcT,
                     kMrcT + kMrcPH);
    o += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" {}>{}</text>\n", X(v), kMrcT + kMrcPH + 15,
                     kMrcFont, mrc_num(v));
  }
  o += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" {}>cache size ({})</text>\n", kMrcL + pw / 2,
                   kMrcT + kMrcPH + 31, kMrcFont, bytes ? "MiB" : "pages");
  o += fmt::format("<text x=\"12\" y=\"{:.1f}\" text-anchor=\"middle\" transform=\"rotate(-90 12 {:.1f})\" {}>miss "
                   "ratio</text>\n",
                   kMrcT + kMrcPH / 2, kMrcT + kMrcPH / 2, kMrcFont);
  if (series.empty())
    o += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" {}>no curves</text>\n", kMrcL + pw / 2,
                     kMrcT + kMrcPH / 2, kMrcFont);
  for (std::size_t i = 0; i < series.size(); ++i) {
    const MissRatioCurve& c = series[i].curve;
    const char* colour = kMrcPalette[i % std::size(kMrcPalette)];
    std::string pts;
    const std::size_t n = std::min(c.capacity.size(), c.miss_ratio.size());
    for (std::size_t k = 0; k < n; ++k)
      pts += fmt::format("{}{:.1f},{:.1f}", k ? " " : "", X(static_cast<double>(c.capacity[k]) * scale),
                         Y(std::clamp(c.miss_ratio[k], 0.0, 1.0)));
    o += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.8\"/>\n", pts, colour);
    std::string legend = series[i].label;
    if (c.knee.found) {
      const double kx = X(static_cast<double>(c.knee.capacity) * scale), ky = Y(std::clamp(c.knee.miss_ratio, 0.0, 1.0));
      const std::string size = bytes ? fmt::format("{:.2f} MiB", static_cast<double>(c.knee.capacity) * scale)
                                     : fmt::format("{} pages", c.knee.capacity);
      const std::string label = fmt::format("knee {}, {:.3f}", size, c.knee.miss_ratio);
      o += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"4\" fill=\"{}\" stroke=\"#fff\"/>\n", kx, ky, colour);
      const bool right = kx < kMrcL + pw * 0.6;  // label on the side with room
      o += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"{}\" {}>{}</text>\n", right ? kx + 7 : kx - 7,
                       ky - 7 - 12.0 * static_cast<double>(i), right ? "start" : "end", kMrcFont, html_escape(label));
      legend += " (" + label + ")";
    }
    const double ly = legend_y + 16.0 * static_cast<double>(i);
    o += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" stroke-width=\"2\"/>\n",
                     kMrcL, kMrcL + 14, ly - 4, ly - 4, colour);
    o += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" {}>{}</text>\n", kMrcL + 20, ly, kMrcFont, html_escape(legend));
  }
  return o + "</svg>\n";
}

}  // namespace vtsim
