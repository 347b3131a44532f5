#include "sim/report/svg_chart.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <utility>

#include "sim/report/html_escape.h"

namespace vtsim {

namespace {

// A text element; text estimated wider than max_w is cut with an ellipsis, the whole in a tooltip.
std::string svgc_text(double x, double y, std::string_view s, const char* cls, const char* anchor, double max_w) {
  return chart_text_svg(x, y, s, cls, anchor, std::string_view(cls) == "title" ? kChartTitlePx : kChartSmallPx, max_w);
}

struct SvgcSwatch {
  std::string label, colour;
  enum Kind { kLine, kDashed, kMark, kBar } kind = kLine;
};

// The legend below the plot: items flow left to right and wrap at the chart's width. Returns the
// markup and the height it takes.
std::pair<std::string, double> svgc_legend(const std::vector<SvgcSwatch>& items, double x0, double y0, double width) {
  std::string o;
  if (items.empty()) return {o, 0};
  double x = x0, y = y0 + 13;
  for (const SvgcSwatch& it : items) {
    const double tw = std::min(chart_text_width(it.label, kChartSmallPx), width - 20);
    if (x > x0 && x + 20 + tw > x0 + width) {
      x = x0;
      y += 16;
    }
    switch (it.kind) {
      case SvgcSwatch::kBar:
        o += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"12\" height=\"9\" fill=\"{}\"/>\n", x, y - 9, it.colour);
        break;
      case SvgcSwatch::kMark:
        o += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"mark\"/>\n", x + 6, x + 6, y - 11, y + 1);
        break;
      default:
        o += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" stroke-width=\"2\"{}/>\n", x,
                         x + 14, y - 4, y - 4, it.colour, it.kind == SvgcSwatch::kDashed ? " stroke-dasharray=\"4,3\"" : "");
    }
    o += svgc_text(x + 18, y, it.label, "lgd", "start", width - 20);
    x += 18 + tw + 16;
  }
  return {o, y - y0 + 5};
}

// A data value for notes and bar ends: 4 significant digits, whole numbers from 1000 up.
std::string svgc_value(double v) {
  if (std::fabs(v) >= 1000 && std::fabs(v) < 1e15) return fmt::format("{:.0f}", v);
  return fmt::format("{:.4g}", v);
}

double svgc_percentile(const std::vector<double>& sorted, double q) {
  const auto n = static_cast<double>(sorted.size());
  const auto i = static_cast<std::size_t>(std::max(1.0, std::ceil(q * n))) - 1;
  return sorted[std::min(i, sorted.size() - 1)];
}

}  // namespace

std::string chart_text_cut(std::string_view s, double px, double max_w) {
  std::string t(s);
  while (!t.empty() && chart_text_width(t + "…", px) > max_w) {
    t.pop_back();
    while (!t.empty() && (static_cast<unsigned char>(t.back()) & 0xC0) == 0x80) t.pop_back();  // whole UTF-8 characters
    if (!t.empty() && static_cast<unsigned char>(t.back()) >= 0xC0) t.pop_back();               // a code point's lead byte
  }
  return t + "…";
}

std::string chart_svg_open(double w, double h, const std::string& label) {
  return fmt::format("<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"chart\" width=\"{:.0f}\" height=\"{:.0f}\" "
                     "viewBox=\"0 0 {:.0f} {:.0f}\" role=\"img\" aria-label=\"{}\">\n",
                     w, h, w, h, html_escape(label));
}

std::string chart_text_svg(double x, double y, std::string_view s, const char* cls, const char* anchor, double px,
                           double max_w, ChartTextFit fit) {
  const double w = chart_text_width(s, px) * (std::string_view(cls) == "title" ? 1.1 : 1.0);  // titles are bold
  if (w <= max_w)
    return fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"{}\" text-anchor=\"{}\">{}</text>\n", x, y, cls, anchor,
                       html_escape(s));
  if (fit == ChartTextFit::cut)
    return fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"{}\" text-anchor=\"{}\"><title>{}</title>{}</text>\n", x, y,
                       cls, anchor, html_escape(s), html_escape(chart_text_cut(s, px, max_w / (w / chart_text_width(s, px)))));
  const double small = std::max(px * max_w / w, px * 0.75);
  const bool cut = small * w / px > max_w;
  return fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"{}\" text-anchor=\"{}\" style=\"font-size:{:.1f}px\">{}{}</text>\n",
                     x, y, cls, anchor, std::floor(small * 10) / 10, cut ? "<title>" + html_escape(s) + "</title>" : "",
                     html_escape(cut ? chart_text_cut(s, small * w / chart_text_width(s, px), max_w) : std::string(s)));
}

const char* chart_colour(std::size_t i) {
  static const char* const kColours[6] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};
  return kColours[i % 6];
}

double chart_text_width(std::string_view s, double px) {
  double em = 0;
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if ((u & 0xC0) == 0x80) continue;  // UTF-8 continuation byte
    if (u >= 0x80) em += 1.0;          // anything beyond ASCII: as wide as CJK
    else if (std::string_view(" .,:;'!|iljtf()[]").find(c) != std::string_view::npos) em += 0.4;
    else if (c == 'm' || c == 'w' || c == 'M' || c == 'W' || c == '@' || c == '%' || c == '#') em += 1.0;
    else if (std::isupper(u)) em += 0.78;
    else em += 0.66;
  }
  return em * px;
}

ChartScale nice_scale(double lo, double hi, int target) {
  ChartScale sc;
  if (!std::isfinite(lo) || !std::isfinite(hi)) lo = 0, hi = 1;
  if (hi < lo) std::swap(lo, hi);
  if (hi == lo) {
    if (lo > 0) lo = 0;
    else if (hi < 0) hi = 0;
    else hi = 1;
  }
  const double raw = (hi - lo) / std::max(1, target);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double n = raw / mag;
  sc.step = (n <= 1 ? 1 : n <= 2 ? 2 : n <= 2.5 ? 2.5 : n <= 5 ? 5 : 10) * mag;
  sc.lo = std::floor(lo / sc.step + 1e-9) * sc.step;
  sc.hi = std::ceil(hi / sc.step - 1e-9) * sc.step;
  for (int k = 0; sc.lo + k * sc.step <= sc.hi + sc.step * 1e-6; ++k) {
    const double v = sc.lo + k * sc.step;
    sc.ticks.push_back(std::fabs(v) < sc.step * 1e-9 ? 0.0 : v);
  }
  sc.max = hi;
  return sc;
}

ChartScale robust_scale(std::vector<double> values) {
  std::erase_if(values, [](double v) { return !std::isfinite(v); });
  if (values.empty()) return nice_scale(0, 1);
  std::sort(values.begin(), values.end());
  const double lo = std::min(0.0, values.front()), max = values.back();
  const double p95 = svgc_percentile(values, 0.95);
  double hi = max;
  if (p95 > 0 && max > 2 * p95) hi = 1.25 * p95;
  ChartScale sc = nice_scale(lo, hi);
  sc.max = max;
  sc.clipped = max > sc.hi * (1 + 1e-9);
  return sc;
}

std::string format_tick(double v, double step) {
  int decimals = 0;
  const double s = std::fabs(step);
  if (s > 0 && std::isfinite(s))
    while (decimals < 9) {
      const double scaled = s * std::pow(10.0, decimals);
      if (std::fabs(scaled - std::round(scaled)) <= 1e-6 * std::max(1.0, scaled)) break;
      ++decimals;
    }
  if (std::fabs(v) < s * 1e-9) v = 0;
  if (std::fabs(v) >= 1e9 || (v != 0 && std::fabs(v) < 1e-4)) return fmt::format("{:.3g}", v);
  return fmt::format("{:.{}f}", v, decimals);
}

std::string time_chart_svg(const TimeChart& c, double W) {
  constexpr double L = 58, R = 16, T = 46, PH = 150;
  const double PW = W - L - R;
  if (c.x.empty()) return {};
  const double x0 = c.x.front(), x1 = std::max(c.x.back(), x0 + 1e-9);
  std::vector<double> all;
  for (const ChartLine& l : c.lines) all.insert(all.end(), l.y.begin(), l.y.end());
  if (c.y_max_hint > 0) all.push_back(c.y_max_hint);
  ChartScale ys;
  if (c.robust) {
    ys = robust_scale(all);
  } else {
    double lo = 0, hi = 0;
    for (double v : all)
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    ys = nice_scale(lo, hi);
  }
  auto X = [&](double v) { return L + (v - x0) / (x1 - x0) * PW; };
  auto Y = [&](double v) { return T + (1 - std::clamp((v - ys.lo) / (ys.hi - ys.lo), 0.0, 1.0)) * PH; };
  std::string body;
  for (double v : ys.ticks) {
    body += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"grid\"/>\n", L, L + PW, Y(v), Y(v));
    body += svgc_text(L - 5, Y(v) + 4, format_tick(v, ys.step), "tick", "end", L - 8);
  }
  // X ticks: round values inside the data's range; a label closer than 8 px to the last one placed
  // is dropped, and the ends are kept inside the chart.
  const ChartScale xs = nice_scale(x0, x1, std::max(2, static_cast<int>(PW / 90)));
  double last_r = -1e9;
  for (double v : xs.ticks) {
    if (v < x0 - 1e-9 * (x1 - x0) || v > x1 + 1e-9 * (x1 - x0)) continue;
    const std::string label = format_tick(v, xs.step) + (c.x_unit.empty() ? "" : " " + c.x_unit);
    const double w = chart_text_width(label, kChartSmallPx);
    const double cx = std::clamp(X(v), w / 2 + 2, W - w / 2 - 2);
    if (cx - w / 2 < last_r + 8) continue;
    last_r = cx + w / 2;
    body += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"grid\"/>\n", X(v), X(v), T + PH, T + PH + 4);
    body += svgc_text(cx, T + PH + 16, label, "tick", "middle", W);
  }
  body += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" class=\"frame\"/>\n", L, T, PW, PH);
  for (double m : c.marks)
    body += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"mark\"/>\n", X(m), X(m), T, T + PH);
  std::vector<SvgcSwatch> legend;
  std::string clip_marks;
  double clip_at = 0;
  const std::size_t n = c.x.size();
  const std::size_t buckets = std::min<std::size_t>(n, 600);
  for (const ChartLine& l : c.lines) {
    if (l.y.size() != n) continue;
    std::string pts;
    double last_y = 0;
    double last_clip_x = -1e9;
    for (std::size_t b = 0; b < buckets; ++b) {
      const std::size_t i0 = b * n / buckets, i1 = std::max(i0 + 1, (b + 1) * n / buckets);
      std::size_t imin = i0, imax = i0;
      for (std::size_t i = i0; i < i1; ++i) {
        if (l.y[i] < l.y[imin]) imin = i;
        if (l.y[i] > l.y[imax]) imax = i;
      }
      for (std::size_t i : {std::min(imin, imax), std::max(imin, imax)}) {
        if (l.step && !pts.empty()) pts += fmt::format("{:.1f},{:.1f} ", X(c.x[i]), Y(last_y));
        pts += fmt::format("{:.1f},{:.1f} ", X(c.x[i]), Y(l.y[i]));
        last_y = l.y[i];
      }
      if (ys.clipped && l.y[imax] > ys.hi && X(c.x[imax]) > last_clip_x + 8) {
        last_clip_x = X(c.x[imax]);
        if (l.y[imax] >= ys.max) clip_at = c.x[imax];
        clip_marks += fmt::format("<path d=\"M{:.1f},{:.1f} l-4,7 h8 z\" fill=\"{}\" class=\"clip\"><title>{}: {} at {} {}</title></path>\n",
                                  X(c.x[imax]), T - 8, l.colour, html_escape(l.label), svgc_value(l.y[imax]),
                                  svgc_value(c.x[imax]), html_escape(c.x_unit));
      }
    }
    body += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.3\"{}/>\n", pts, l.colour,
                        l.dashed ? " stroke-dasharray=\"5,3\"" : "");
    legend.push_back({l.label, l.colour, l.dashed ? SvgcSwatch::kDashed : SvgcSwatch::kLine});
  }
  if (!c.marks.empty() && !c.marks_label.empty()) legend.push_back({c.marks_label, "#d33", SvgcSwatch::kMark});
  auto [lg, lg_h] = svgc_legend(legend, 8, T + PH + 22, W - 16);
  double h = T + PH + 22 + lg_h;
  if (ys.clipped) {
    lg += svgc_text(8, h + 14,
                    fmt::format("▲ off the scale: max {} {} at {} {} (the scale fits 95 % of the values; docs/report.md)",
                                svgc_value(ys.max), c.y_unit, svgc_value(clip_at), c.x_unit),
                    "lgd", "start", W - 16);
    h += 18;
  }
  std::string o = chart_svg_open(W, h + 8, c.title);
  o += svgc_text(8, 18, c.title, "title", "start", W - 16);
  o += svgc_text(8, 34, c.subtitle.empty() ? c.y_unit : c.subtitle + (c.y_unit.empty() ? "" : " (" + c.y_unit + ")"), "sub",
                 "start", W - 16);
  return o + body + clip_marks + lg + "</svg>\n";
}

std::string bar_chart_svg(const std::string& title, const std::string& subtitle, const std::vector<std::string>& groups,
                          const std::vector<BarSeries>& series, double W) {
  constexpr double T = 46, BarH = 11, GroupGap = 8, ValueW = 64, R = 8;
  double label_w = 0;
  for (const std::string& g : groups) label_w = std::max(label_w, chart_text_width(g, kChartSmallPx));
  label_w = std::min(label_w + 4, W * 0.35);
  const double L = 8 + label_w + 6, PW = W - L - ValueW - R;
  std::vector<double> all;
  for (const BarSeries& s : series)
    for (double v : s.v)
      if (std::isfinite(v)) all.push_back(v);
  const ChartScale sc = robust_scale(all);
  auto X = [&](double v) { return L + std::clamp((v - sc.lo) / (sc.hi - sc.lo), 0.0, 1.0) * PW; };
  const double group_h = BarH * static_cast<double>(std::max<std::size_t>(1, series.size())) + GroupGap;
  const double PH = group_h * static_cast<double>(groups.size());
  std::string body;
  for (double v : sc.ticks) {
    body += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"grid\"/>\n", X(v), X(v), T, T + PH);
  }
  double last_r = -1e9;
  for (double v : sc.ticks) {
    const std::string label = format_tick(v, sc.step);
    const double w = chart_text_width(label, kChartSmallPx);
    if (X(v) - w / 2 < last_r + 8) continue;
    last_r = X(v) + w / 2;
    body += svgc_text(X(v), T + PH + 14, label, "tick", "middle", W);
  }
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const double gy = T + static_cast<double>(g) * group_h;
    body += svgc_text(L - 6, gy + group_h / 2 + 4 - GroupGap / 2, groups[g], "tick", "end", label_w);
    for (std::size_t k = 0; k < series.size(); ++k) {
      if (g >= series[k].v.size() || !std::isfinite(series[k].v[g])) continue;
      const double v = series[k].v[g], y = gy + BarH * static_cast<double>(k);
      const double xa = X(std::min(0.0, v)), xb = X(std::max(0.0, v));
      body += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" fill=\"{}\"><title>{}: {}</title></rect>\n",
                          xa, y, std::max(0.5, xb - xa), BarH - 2, series[k].colour, html_escape(series[k].label),
                          svgc_value(v));
      const bool off = v > sc.hi * (1 + 1e-9);
      if (series.size() == 1 || off)  // one series: every value; several: only those past the scale
        body += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"val\">{}{}</text>\n", xb + 3, y + BarH - 3,
                            svgc_value(v), off ? " ▶" : "");
    }
  }
  std::vector<SvgcSwatch> items;
  if (series.size() > 1)
    for (const BarSeries& s : series) items.push_back({s.label, s.colour, SvgcSwatch::kBar});
  auto [lg, lg_h] = svgc_legend(items, 8, T + PH + 20, W - 16);
  const double h = T + PH + 20 + lg_h;
  std::string o = chart_svg_open(W, h + 8, title);
  o += svgc_text(8, 18, title, "title", "start", W - 16);
  o += svgc_text(8, 34, subtitle, "sub", "start", W - 16);
  return o + body + lg + "</svg>\n";
}

}  // namespace vtsim
