#include "sim/report/sweep_report.h"

#include "cache/policy/mrc.h"
#include "sim/report/mrc_chart.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string_view>
#include <tuple>

#include "core/text.h"
#include "sim/run/metric_direction.h"
#include "sim/run/metric_path.h"
#include "sim/report/html_escape.h"
#include "sim/report/svg_chart.h"

// Helpers live in a named namespace: unity builds put this file in one translation unit with
// others whose anonymous namespaces already hold `escape`, `chart`, `Series`.
namespace vtsim::sweep_report_detail {

using nlohmann::json;
using Opt = std::optional<double>;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::size_t kMaxLines = 6;  // more combinations than this: mean and min–max band

// ---- text ----------------------------------------------------------------------------------

// 3 significant figures, k/M/G from 10^4, exponent below 10^-3: compact, locale-free.
std::string fmt3(double v) {
  if (std::isnan(v)) return "n/a";
  if (std::isinf(v)) return v > 0 ? "∞" : "-∞";
  if (v == 0) return "0";
  int e = static_cast<int>(std::floor(std::log10(std::fabs(v))));
  const double unit = std::pow(10.0, e - 2);
  const double r = std::round(v / unit) * unit;
  if (std::fabs(r) >= std::pow(10.0, e + 1)) ++e;  // 999.6 rounds to 1000
  const double a = std::fabs(r);
  if (a >= 1e13) return fmt::format("{:.2e}", r);
  if (a >= 1e4) {
    const double div = a >= 1e9 ? 1e9 : a >= 1e6 ? 1e6 : 1e3;
    return fmt3(r / div) + (div == 1e9 ? "G" : div == 1e6 ? "M" : "k");
  }
  if (a < 1e-3) return fmt::format("{:.2e}", r);
  std::string s = fmt::format("{:.{}f}", r, std::max(0, 2 - e));
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  return s;
}

std::string fmt3(const Opt& v) { return v ? fmt3(*v) : "n/a"; }

std::string count_of(std::size_t n, const char* noun) { return fmt::format("{} {}{}", n, noun, n == 1 ? "" : "s"); }

// A config value as the spec wrote it in TOML ("256", "\"hdd\"", "true"), without the quotes.
std::string shown(const std::string& toml) {
  if (toml.size() >= 2 && (toml.front() == '"' || toml.front() == '\'') && toml.back() == toml.front())
    return toml.substr(1, toml.size() - 2);
  return toml;
}

Opt toml_number(const std::string& toml) {
  std::string t;
  for (char c : toml)
    if (c != '_') t += c;  // TOML digit separators
  if (!t.empty() && t.front() == '+') t.erase(0, 1);
  double v = 0;
  if (!text::parse_whole(t, v) || !std::isfinite(v)) return std::nullopt;
  return v;
}

// ---- input -----------------------------------------------------------------------------------

const json& field(const json& j, const char* key) {
  static const json none;
  if (!j.is_object()) return none;
  const auto it = j.find(key);
  return it == j.end() ? none : *it;
}

const json& array_of(const json& j) {
  static const json empty = json::array();
  return j.is_array() ? j : empty;
}

std::string text_of(const json& j) { return j.is_string() ? j.get<std::string>() : j.is_null() ? "" : j.dump(); }

std::optional<std::size_t> index_of(const json& j) {
  if (!j.is_number_integer()) return std::nullopt;
  const auto v = j.get<long long>();
  if (v < 0) return std::nullopt;
  return static_cast<std::size_t>(v);
}

// A dotted path into a summary ("popin.time_to_sharp_s.mean"; array elements by number).
Opt metric_at(const json& summary, std::string_view path) {
  const json* p = summary_path(summary, path);
  if (!p || !p->is_number()) return std::nullopt;
  const double v = p->get<double>();
  return std::isfinite(v) ? Opt(v) : std::nullopt;
}

struct Axis {
  std::string key;
  std::vector<std::string> values;  // TOML text, spec order
};

struct Config {
  std::map<std::string, std::string> values;  // key -> TOML text
  json cost;
};

struct TraceInfo {
  std::string name, source;
};

// The blur bound of the Pareto fronts when the meta has none (docs/sweep.md, `blur_bound`).
constexpr double kDefaultBlurBound = 0.05;

struct Sweep {
  std::string name, hash;
  double blur_bound = kDefaultBlurBound;  // fronts only among configs whose mean blurry fraction is at most this
  std::vector<Axis> axes;
  std::vector<std::string> keys;     // every key a config sets
  std::vector<std::string> metrics;
  std::vector<Config> configs;
  std::vector<TraceInfo> traces;
  std::vector<std::vector<const json*>> row_at;  // [config][trace], null when the sweep wrote none
  std::vector<const json*> failed;               // rows whose status is not "ok", by (config, trace)
};

bool row_ok(const json* row) { return row && field(*row, "status") == "ok" && field(*row, "summary").is_object(); }

std::string row_error(const json& row) {
  const json& e = field(row, "error");
  if (!e.is_null()) return text_of(e);
  return fmt::format("status {}", text_of(field(row, "status")));
}

Sweep load_sweep(const json& meta, const std::vector<json>& rows) {
  Sweep s;
  s.name = text_of(field(meta, "name"));
  s.hash = text_of(field(meta, "spec_hash"));
  if (const json& bb = field(meta, "blur_bound"); bb.is_number() && std::isfinite(bb.get<double>())) s.blur_bound = bb.get<double>();
  for (const json& a : array_of(field(meta, "axes"))) {
    Axis ax{text_of(field(a, "key")), {}};
    for (const json& v : array_of(field(a, "values"))) ax.values.push_back(text_of(v));
    s.axes.push_back(std::move(ax));
  }
  auto add_key = [&s](const std::string& k) {
    if (std::find(s.keys.begin(), s.keys.end(), k) == s.keys.end()) s.keys.push_back(k);
  };
  for (const Axis& a : s.axes) add_key(a.key);
  for (const json& k : array_of(field(meta, "axis_keys"))) add_key(text_of(k));
  for (const json& m : array_of(field(meta, "metrics"))) s.metrics.push_back(text_of(m));

  const json& configs = array_of(field(meta, "configs"));
  const json& traces = array_of(field(meta, "traces"));
  // Indices beyond every list given are corrupt input: they would only make the tables huge.
  const std::size_t cap = configs.size() + traces.size() + rows.size();
  for (std::size_t i = 0; i < configs.size(); ++i) {
    const std::size_t c = index_of(field(configs[i], "config")).value_or(i);
    if (c >= cap) continue;
    if (c >= s.configs.size()) s.configs.resize(c + 1);
    if (field(configs[i], "values").is_object())
      for (const auto& [k, v] : field(configs[i], "values").items()) s.configs[c].values[k] = text_of(v);
    s.configs[c].cost = field(configs[i], "cost");
  }
  for (std::size_t i = 0; i < traces.size(); ++i) {
    const std::size_t t = index_of(field(traces[i], "trace")).value_or(i);
    if (t >= cap) continue;
    if (t >= s.traces.size()) s.traces.resize(t + 1);
    s.traces[t] = {text_of(field(traces[i], "name")), text_of(field(traces[i], "source"))};
  }
  for (const json& row : rows) {
    const auto c = index_of(field(row, "config")), t = index_of(field(row, "trace"));
    if (!row_ok(&row)) s.failed.push_back(&row);
    if (!c || !t || *c >= cap || *t >= cap) continue;
    if (*c >= s.configs.size()) s.configs.resize(*c + 1);
    if (*t >= s.traces.size()) s.traces.resize(*t + 1);
    if (s.configs[*c].values.empty() && field(row, "values").is_object())  // a config the meta lacks
      for (const auto& [k, v] : field(row, "values").items()) s.configs[*c].values[k] = text_of(v);
  }
  for (const Config& c : s.configs)
    for (const auto& kv : c.values) add_key(kv.first);
  // Failed rows by (config, trace), so the page does not depend on the order rows arrive in.
  auto place = [](const json* r) {
    return std::pair{index_of(field(*r, "config")).value_or(SIZE_MAX), index_of(field(*r, "trace")).value_or(SIZE_MAX)};
  };
  std::stable_sort(s.failed.begin(), s.failed.end(), [&](const json* a, const json* b) { return place(a) < place(b); });
  s.row_at.assign(s.configs.size(), std::vector<const json*>(s.traces.size(), nullptr));
  for (const json& row : rows) {
    const auto c = index_of(field(row, "config")), t = index_of(field(row, "trace"));
    if (c && t && *c < cap && *t < cap) s.row_at[*c][*t] = &row;
  }
  return s;
}

// One metric over the sweep: its value per (config, trace) and per config the mean over traces.
// A config's mean needs a value on every trace, so all means compare the same traces.
struct MetricData {
  std::string path;
  std::vector<std::vector<Opt>> cell;  // [config][trace]
  std::vector<Opt> mean;               // [config]
};

MetricData gather(const Sweep& s, const std::string& path) {
  MetricData m{path, {}, {}};
  for (const auto& per_trace : s.row_at) {
    std::vector<Opt> cells;
    for (const json* row : per_trace) cells.push_back(row_ok(row) ? metric_at(field(*row, "summary"), path) : std::nullopt);
    m.cell.push_back(std::move(cells));
  }
  // A trace on which no config has a value (null: a time to sharp on a trace without an event)
  // is left out of every mean, rather than making every mean n/a or counting it as 0; a trace on
  // which some configs have one still needs it from all.
  std::vector<bool> counts(s.traces.size(), false);
  for (std::size_t t = 0; t < s.traces.size(); ++t)
    for (std::size_t c = 0; c < s.row_at.size(); ++c)
      counts[t] = counts[t] || (t < m.cell[c].size() && m.cell[c][t]) || (t < s.row_at[c].size() && !row_ok(s.row_at[c][t]));
  for (std::size_t c = 0; c < s.row_at.size(); ++c) {
    double sum = 0;
    std::size_t n = 0;
    bool all = !s.row_at[c].empty();
    for (std::size_t t = 0; t < m.cell[c].size(); ++t) {
      if (!counts[t]) continue;
      if (m.cell[c][t]) sum += *m.cell[c][t], ++n;
      else all = false;
    }
    m.mean.push_back(all && n > 0 ? Opt(sum / static_cast<double>(n)) : std::nullopt);
  }
  return m;
}

// -1: lower is better, +1: higher is better, 0: no better direction (docs/metrics.md, "Directions":
// the table compare reads too, sim/run/metric_direction.h).
int direction(const std::string& metric) {
  switch (metric_direction(metric)) {
    case MetricDirection::lower: return -1;
    case MetricDirection::higher: return +1;
    default: return 0;
  }
}

const char* direction_text(int dir) { return dir < 0 ? "lower is better" : dir > 0 ? "higher is better" : "no better direction"; }

// The unit a metric's name carries (docs/metrics.md names them so), for axis titles.
std::string unit_of(const std::string& metric) {
  if (metric.find("_ms") != std::string::npos) return "ms";
  if (metric.find("MBps") != std::string::npos) return "MB/s";
  if (metric.find("bytes") != std::string::npos) return "bytes";
  if (metric.find("fraction") != std::string::npos || metric.find("ratio") != std::string::npos) return "fraction 0–1";
  if (metric.find("_s.") != std::string::npos || (metric.size() > 2 && metric.ends_with("_s"))) return "s";
  return "";
}

std::string config_values_text(const Sweep& s, std::size_t c) {
  std::string o;
  for (const std::string& k : s.keys) {
    const auto it = s.configs[c].values.find(k);
    if (it == s.configs[c].values.end()) continue;
    o += fmt::format("{}{}={}", o.empty() ? "" : ", ", k, shown(it->second));
  }
  return o.empty() ? "base config" : o;
}

std::string config_value(const Sweep& s, std::size_t c, const std::string& key) {
  const auto it = s.configs[c].values.find(key);
  return it == s.configs[c].values.end() ? "–" : shown(it->second);
}

// "walk" for traces/walk.csv; a generated trace's first word; the full name goes in a tooltip.
std::string trace_short(const Sweep& s, std::size_t t) {
  const TraceInfo& ti = s.traces[t];
  std::string n = ti.source.empty() ? ti.name : ti.source;
  if (const auto slash = n.find_last_of('/'); slash != std::string::npos && !ti.source.empty()) n = n.substr(slash + 1);
  if (const auto dot = n.find_last_of('.'); dot != std::string::npos && dot > 0 && !ti.source.empty()) n = n.substr(0, dot);
  if (const auto sp = n.find(' '); sp != std::string::npos) n = n.substr(0, sp);
  return fmt::format("{}: {}", t, n.empty() ? "trace" : n);
}

// ---- scales ----------------------------------------------------------------------------------

// A linear scale over data: round ticks (1, 2, 2.5, 5 × 10^k, about 4 of them), 0 included when
// the data start near it, and an upper bound set by the data's bulk: a maximum over 20× the 95th
// percentile is clipped (the chart marks what lies above).
struct Scale {
  double lo = 0, hi = 1;
  std::vector<double> ticks;
  bool clipped = false;
  double max = 0;  // the largest value, clipped or not
  double frac(double v) const { return std::clamp((v - lo) / (hi - lo), 0.0, 1.0); }
  bool above(double v) const { return v > hi * (1 + 1e-9) + 1e-300; }
};

Scale make_scale(std::vector<double> vals, bool from_zero = false) {
  Scale sc;
  if (vals.empty()) {
    sc.ticks = {0, 0.5, 1};
    return sc;
  }
  std::sort(vals.begin(), vals.end());
  double lo = vals.front(), hi = vals.back();
  sc.max = hi;
  const double p95 = vals[static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(vals.size()))) - 1];
  if (p95 > 0 && hi > 20 * p95) {
    hi = *std::prev(std::upper_bound(vals.begin(), vals.end(), 20 * p95));
    sc.clipped = true;
  }
  if (lo >= 0 && (from_zero || lo <= 0.5 * hi)) lo = 0;
  if (hi <= 0 && (from_zero || hi >= 0.5 * lo)) hi = 0;
  if (lo == hi) {
    if (lo > 0) lo = 0;
    else if (hi < 0) hi = 0;
    else hi = 1;
  }
  const double raw = (hi - lo) / 4;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double n = raw / mag;
  const double step = (n <= 1 ? 1 : n <= 2 ? 2 : n <= 2.5 ? 2.5 : n <= 5 ? 5 : 10) * mag;
  sc.lo = std::floor(lo / step + 1e-9) * step;
  sc.hi = std::ceil(hi / step - 1e-9) * step;
  for (int k = 0; sc.lo + k * step <= sc.hi + step * 1e-6; ++k) {
    const double v = sc.lo + k * step;
    sc.ticks.push_back(std::fabs(v) < step * 1e-9 ? 0.0 : v);
  }
  return sc;
}

// ---- SVG pieces ------------------------------------------------------------------------------

struct Tick {
  double x;
  std::string label;
  bool must = false;  // placed first ("no limit"); the others make room
};

// X tick labels centred under their positions, each squeezed to max_w and kept inside the chart;
// a label that would come within 6 px of one already placed is dropped: labels never overlap.
std::string x_tick_labels(const std::vector<Tick>& ticks, double y, double chart_w, double max_w) {
  std::string o;
  std::vector<std::pair<double, double>> placed;
  for (const bool must : {true, false})
    for (const Tick& t : ticks) {
      if (t.must != must) continue;
      const double w = std::min(chart_text_width(t.label, kChartSmallPx), max_w);
      const double cx = std::clamp(t.x, w / 2 + 2, chart_w - w / 2 - 2);
      const double l = cx - w / 2, r = cx + w / 2;
      if (std::any_of(placed.begin(), placed.end(), [&](const auto& p) { return l < p.second + 6 && p.first < r + 6; })) continue;
      placed.emplace_back(l, r);
      o += chart_text_svg(cx, y, t.label, "tick", "middle", kChartSmallPx, max_w, ChartTextFit::shrink);
    }
  return o;
}

// The y axis: grid lines across the plot and the tick values right-aligned left of it.
std::string y_axis(const Scale& sc, double left, double right, const auto& Y) {
  std::string o;
  for (double v : sc.ticks) {
    o += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"grid\"/>\n", left, right, Y(v), Y(v));
    o += chart_text_svg(left - 5, Y(v) + 4, fmt3(v), "tick", "end", kChartSmallPx, left - 8, ChartTextFit::shrink);
  }
  return o;
}

struct Swatch {
  std::string label, colour;
  bool band = false;
};

// A legend below the plot: a heading line, then the items flowing left to right and wrapping at
// the chart's width. Returns the markup and the height it takes.
std::pair<std::string, double> legend_below(const std::string& heading, const std::vector<Swatch>& items, double x0, double y0,
                                            double width) {
  std::string o;
  double y = y0;
  if (!heading.empty()) {
    y += 12;
    o += chart_text_svg(x0, y, heading, "lgd", "start", kChartSmallPx, width, ChartTextFit::shrink);
  }
  double x = x0;
  if (!items.empty()) y += 15;
  for (const Swatch& it : items) {
    const double tw = std::min(chart_text_width(it.label, kChartSmallPx), width - 16);
    if (x > x0 && x + 16 + tw > x0 + width) {
      x = x0;
      y += 15;
    }
    if (it.band)
      o += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"12\" height=\"9\" fill=\"{}\" fill-opacity=\"0.2\"/>\n", x, y - 8,
                       it.colour);
    else
      o += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" stroke-width=\"2\"/>"
                       "<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"2.5\" fill=\"{}\"/>\n",
                       x, x + 12, y - 4, y - 4, it.colour, x + 6, y - 4, it.colour);
    o += chart_text_svg(x + 16, y, it.label, "lgd", "start", kChartSmallPx, width - 16, ChartTextFit::shrink);
    x += 16 + tw + 14;
  }
  return {o, y - y0 + (items.empty() && heading.empty() ? 0 : 6)};
}

// ---- line charts: a metric over one axis -----------------------------------------------------

struct XSlots {
  std::string title;
  std::vector<std::string> labels;  // one per axis value, spec order
  std::vector<double> pos;          // 0..1 across the plot
};

// Numeric values with a positive range sit at their value (log scale when they span 8× or more,
// as doubling sweeps of sizes do); anything else (text, booleans, sentinels such as -1 or 0 for
// "no limit") is categorical, in spec order.
XSlots axis_slots(const Axis& ax) {
  XSlots xs{ax.key, {}, {}};
  std::vector<double> v;
  for (const std::string& t : ax.values) {
    xs.labels.push_back(shown(t));
    if (const Opt n = toml_number(t)) v.push_back(*n);
  }
  const std::size_t n = ax.values.size();
  const bool numeric = v.size() == n && n >= 2 && *std::min_element(v.begin(), v.end()) > 0 &&
                       *std::max_element(v.begin(), v.end()) > *std::min_element(v.begin(), v.end());
  if (!numeric) {
    for (std::size_t i = 0; i < n; ++i) xs.pos.push_back((static_cast<double>(i) + 0.5) / static_cast<double>(n));
    return xs;
  }
  const double lo = *std::min_element(v.begin(), v.end()), hi = *std::max_element(v.begin(), v.end());
  const bool log = hi / lo >= 8;
  if (log) xs.title += " (log scale)";
  auto f = [log](double a) { return log ? std::log(a) : a; };
  for (double a : v) xs.pos.push_back(0.06 + 0.88 * (f(a) - f(lo)) / (f(hi) - f(lo)));
  return xs;
}

struct Line {
  std::string label;
  std::vector<Opt> y;  // one per slot
};

struct Band {
  std::vector<Opt> lo, mid, hi;  // one per slot
  std::size_t members = 0;
};

// A triangle at the top of the plot for a value above the (clipped) scale.
std::string clip_mark(double x, double top, const char* colour) {
  return fmt::format("<path d=\"M{:.1f},{:.1f} l-4,7 h8 z\" fill=\"{}\" class=\"clip\"/>\n", x, top, colour);
}

std::string clip_note(const Scale& sc, double x, double y, double width, const char* mark = "▲") {
  return chart_text_svg(x, y, fmt::format("{} off the scale: max {} (scale fits the bulk of the data)", mark, fmt3(sc.max)),
                        "lgd", "start", kChartSmallPx, width, ChartTextFit::shrink);
}

// A band, when given, is drawn instead of the lines (which then only set the scale).
std::string line_chart(const std::string& title, const std::string& subtitle, const XSlots& xs, const std::vector<Line>& lines,
                       const Band* band, const std::string& legend_heading, double W) {
  constexpr double L = 58, R = 18, T = 46, PH = 150;
  const double PW = W - L - R;
  // The scale comes from every line's values, also when a band stands in for them: a band's
  // extremes alone would let one outlier set it.
  std::vector<double> vals;
  for (const Line& l : lines)
    for (const Opt& v : l.y)
      if (v) vals.push_back(*v);
  const Scale sc = make_scale(vals);
  auto X = [&](std::size_t slot) { return L + xs.pos[slot] * PW; };
  auto Y = [&](double v) { return T + (1 - sc.frac(v)) * PH; };
  std::vector<std::size_t> order(xs.pos.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return xs.pos[a] < xs.pos[b]; });

  std::string body = y_axis(sc, L, L + PW, Y);
  std::vector<Tick> ticks;
  for (std::size_t i : order) ticks.push_back({X(i), xs.labels[i]});
  const double slot_w = xs.pos.size() > 1 ? PW / static_cast<double>(xs.pos.size()) : PW;
  body += x_tick_labels(ticks, T + PH + 15, W, std::max(slot_w - 6, 36.0));
  body += chart_text_svg(L + PW / 2, T + PH + 31, xs.title, "lgd", "middle", kChartSmallPx, W - 16, ChartTextFit::shrink);
  if (band) {
    // The band's outline: the maxima left to right, then the minima back, over slots with both.
    std::string pts;
    for (std::size_t i : order)
      if (band->hi[i]) pts += fmt::format("{:.1f},{:.1f} ", X(i), Y(*band->hi[i]));
    for (auto it = order.rbegin(); it != order.rend(); ++it)
      if (band->lo[*it]) pts += fmt::format("{:.1f},{:.1f} ", X(*it), Y(*band->lo[*it]));
    body += fmt::format("<polygon points=\"{}\" fill=\"{}\" fill-opacity=\"0.2\" stroke=\"none\"/>\n", pts, chart_colour(0));
  }
  bool any_clipped = false;
  auto draw = [&](const std::vector<Opt>& y, const char* colour) {
    std::string pts;
    auto flush = [&] {
      if (!pts.empty())
        body += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.8\"/>\n", pts, colour);
      pts.clear();
    };
    for (std::size_t i : order) {
      if (!y[i]) {
        flush();  // n/a breaks the line
        continue;
      }
      pts += fmt::format("{:.1f},{:.1f} ", X(i), Y(*y[i]));
      body += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"2.8\" fill=\"{}\"><title>{}: {}</title></circle>\n", X(i),
                          Y(*y[i]), colour, html_escape(xs.labels[i]), fmt3(*y[i]));
      if (sc.above(*y[i])) {
        body += clip_mark(X(i), T - 9, colour);
        any_clipped = true;
      }
    }
    flush();
  };
  std::vector<Swatch> items;
  if (band) {
    draw(band->mid, chart_colour(0));
    items = {{fmt::format("mean of {} combinations", band->members), chart_colour(0), false}, {"min–max", chart_colour(0), true}};
  } else {
    for (std::size_t k = 0; k < lines.size(); ++k) {
      draw(lines[k].y, chart_colour(k % kMaxLines));
      if (lines.size() > 1) items.push_back({lines[k].label, chart_colour(k % kMaxLines), false});
    }
  }
  auto [legend, legend_h] = legend_below(items.empty() ? "" : legend_heading, items, 8, T + PH + 38, W - 16);
  double h = T + PH + 38 + legend_h;
  if (any_clipped) {
    legend += clip_note(sc, 8, h + 12, W - 16);
    h += 18;
  }
  std::string o = chart_svg_open(W, h + 6, title);
  o += chart_text_svg(8, 18, title, "title", "start", kChartTitlePx, W - 16, ChartTextFit::shrink);
  o += chart_text_svg(8, 34, subtitle, "sub", "start", kChartSmallPx, W - 16, ChartTextFit::shrink);
  return o + body + legend + "</svg>\n";
}

// ---- bar charts: a metric per config when the sweep has no axes -----------------------------

std::string bar_chart(const std::string& title, const std::string& subtitle, const std::vector<std::pair<std::string, Opt>>& bars) {
  constexpr double W = 600, T = 46, RowH = 18, ValueW = 52;
  double label_w = 0;
  for (const auto& b : bars) label_w = std::max(label_w, chart_text_width(b.first, kChartSmallPx));
  label_w = std::min(label_w, 240.0);
  const double L = 8 + label_w + 6, PW = W - L - ValueW - 8;
  std::vector<double> vals;
  for (const auto& b : bars)
    if (b.second) vals.push_back(*b.second);
  const Scale sc = make_scale(vals, true);  // a bar's length is its value
  auto X = [&](double v) { return L + sc.frac(v) * PW; };
  std::string body;
  const double PH = RowH * static_cast<double>(bars.size());
  for (double v : sc.ticks)
    body += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"grid\"/>\n", X(v), X(v), T, T + PH);
  std::vector<Tick> ticks;
  for (double v : sc.ticks) ticks.push_back({X(v), fmt3(v)});
  body += x_tick_labels(ticks, T + PH + 14, W, 60);
  bool any_clipped = false;
  for (std::size_t i = 0; i < bars.size(); ++i) {
    const double y = T + RowH * static_cast<double>(i);
    body += chart_text_svg(L - 6, y + 13, bars[i].first, "tick", "end", kChartSmallPx, label_w, ChartTextFit::shrink);
    if (!bars[i].second) {
      body += chart_text_svg(L + 4, y + 13, "n/a", "tick", "start", kChartSmallPx, 40, ChartTextFit::shrink);
      continue;
    }
    const double v = *bars[i].second, x0 = X(std::clamp(0.0, sc.lo, sc.hi)), x1 = X(v);
    body += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.0f}\" fill=\"{}\"/>\n", std::min(x0, x1),
                        y + 3, std::fabs(x1 - x0), RowH - 6, chart_colour(0));
    const bool clipped = sc.above(v);
    any_clipped = any_clipped || clipped;
    body += chart_text_svg(std::max(x0, x1) + 4, y + 13, fmt3(v) + (clipped ? " ▶" : ""), "tick", "start", kChartSmallPx, ValueW,
                           ChartTextFit::shrink);
  }
  double h = T + PH + 20;
  if (any_clipped) {
    body += clip_note(sc, 8, h + 12, W - 16, "▶");
    h += 18;
  }
  std::string o = chart_svg_open(W, h + 6, title);
  o += chart_text_svg(8, 18, title, "title", "start", kChartTitlePx, W - 16, ChartTextFit::shrink);
  o += chart_text_svg(8, 34, subtitle, "sub", "start", kChartSmallPx, W - 16, ChartTextFit::shrink);
  return o + body + "</svg>\n";
}

// ---- Pareto scatter ---------------------------------------------------------------------------

struct Point {
  std::size_t config;
  double x, y;  // x = +inf: no limit
};

struct Box {
  double x0, y0, x1, y1;
  bool hits(const Box& b) const { return x0 < b.x1 && b.x0 < x1 && y0 < b.y1 && b.y0 < y1; }
};

std::string pareto_chart(const std::string& title, const std::string& subtitle, const std::string& x_title,
                         const std::vector<Point>& pts, const std::vector<std::size_t>& front) {
  constexpr double W = 480, L = 58, R = 18, T = 46, PH = 220, PW = W - L - R;
  std::vector<double> xv, yv;
  bool unlimited = false;
  for (const Point& p : pts) {
    if (std::isinf(p.x)) unlimited = true;
    else xv.push_back(p.x);
    yv.push_back(p.y);
  }
  const Scale xs = make_scale(xv), ys = make_scale(yv);
  // "No limit" gets a column of its own right of the finite costs, past a dashed line.
  const double finite_w = unlimited ? PW * 0.84 : PW;
  auto X = [&](double v) { return std::isinf(v) ? L + PW * 0.93 : L + xs.frac(v) * finite_w; };
  auto Y = [&](double v) { return T + (1 - ys.frac(v)) * PH; };
  std::string body = y_axis(ys, L, L + PW, Y);
  std::vector<Tick> ticks;
  for (double v : xs.ticks) ticks.push_back({X(v), fmt3(v)});
  if (unlimited) {
    ticks.push_back({X(kInf), "no limit", true});
    body += fmt::format("<line x1=\"{0:.1f}\" x2=\"{0:.1f}\" y1=\"{1:.1f}\" y2=\"{2:.1f}\" class=\"sep\"/>\n", L + PW * 0.87, T,
                        T + PH);
  }
  body += x_tick_labels(ticks, T + PH + 15, W, 64);
  body += chart_text_svg(L + PW / 2, T + PH + 31, x_title, "lgd", "middle", kChartSmallPx, W - 16, ChartTextFit::shrink);
  bool clipped = false;
  auto plot_y = [&](double v) {
    clipped = clipped || ys.above(v);
    return Y(v);
  };
  auto plot_x = [&](double v) {
    clipped = clipped || (!std::isinf(v) && xs.above(v));
    return X(v);
  };
  for (const Point& p : pts)
    body += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"3.5\" class=\"pt\"><title>#{}: {} × {}</title></circle>\n",
                        plot_x(p.x), plot_y(p.y), p.config, fmt3(p.x), fmt3(p.y));
  std::string stair;
  for (std::size_t k = 0; k < front.size(); ++k) {
    const Point& p = pts[front[k]];
    stair += k == 0 ? fmt::format("M{:.1f},{:.1f}", X(p.x), Y(p.y)) : fmt::format(" H{:.1f} V{:.1f}", X(p.x), Y(p.y));
  }
  if (!stair.empty()) body += fmt::format("<path d=\"{}\" class=\"stair\"/>\n", stair);
  // Front labels "#config" beside their points, skipped where they would cover another label.
  std::vector<Box> taken;
  for (std::size_t k : front) {
    const Point& p = pts[k];
    body += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"4.5\" class=\"front\"><title>#{}: {} × {}</title></circle>\n",
                        X(p.x), Y(p.y), p.config, fmt3(p.x), fmt3(p.y));
    const std::string label = fmt::format("#{}", p.config);
    const double w = chart_text_width(label, kChartSmallPx);
    const std::pair<double, double> spots[] = {{6, -6}, {6, 14}, {-6 - w, -6}, {-6 - w, 14}};
    for (const auto& [dx, dy] : spots) {
      const Box b{X(p.x) + dx, Y(p.y) + dy - 10, X(p.x) + dx + w, Y(p.y) + dy + 2};
      if (b.x0 < L || b.x1 > W - 2 || b.y0 < T - 4 || b.y1 > T + PH) continue;
      if (std::any_of(taken.begin(), taken.end(), [&](const Box& o) { return o.hits(b); })) continue;
      taken.push_back(b);
      body += chart_text_svg(b.x0, b.y1 - 2, label, "flabel", "start", kChartSmallPx, w + 1, ChartTextFit::shrink);
      break;
    }
  }
  auto [legend, legend_h] = legend_below("", {{"config (mean over traces)", "#9a9a9a", false}, {"Pareto front", "#d62728", false}},
                                         8, T + PH + 38, W - 16);
  double h = T + PH + 38 + legend_h;
  if (clipped) {
    legend += chart_text_svg(8, h + 12,
                             fmt::format("points off the scale sit on its edge (max cost {}, max pop-in {})", fmt3(xs.max), fmt3(ys.max)),
                             "lgd", "start", kChartSmallPx, W - 16, ChartTextFit::shrink);
    h += 18;
  }
  std::string o = chart_svg_open(W, h + 6, title);
  o += chart_text_svg(8, 18, title, "title", "start", kChartTitlePx, W - 16, ChartTextFit::shrink);
  o += chart_text_svg(8, 34, subtitle, "sub", "start", kChartSmallPx, W - 16, ChartTextFit::shrink);
  return o + body + legend + "</svg>\n";
}

// ---- sections ---------------------------------------------------------------------------------

const char* const kStyle =
    "body{font:14px/1.4 system-ui,sans-serif;margin:24px auto;max-width:1240px;padding:0 16px;color:#222}"
    "h1{font-size:22px;margin:0 0 8px}h2{font-size:18px;margin:32px 0 8px;border-bottom:1px solid #ddd;padding-bottom:4px}"
    "h3{font-size:15px;margin:18px 0 6px}p.note{color:#555;margin:4px 0 8px;font-size:13px}"
    ".charts{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start}"
    ".pair{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start;margin-bottom:14px}"
    "svg.chart{display:block;flex:none;background:#fcfcfc;border:1px solid #e5e5e5}"
    "svg .title{font:600 13px system-ui,sans-serif;fill:#222}svg .sub,svg .tick,svg .lgd,svg .flabel{font:11px system-ui,sans-serif;fill:#555}"
    "svg .flabel{fill:#b22222}svg .grid{stroke:#e8e8e8}svg .sep{stroke:#999;stroke-dasharray:3,3}"
    "svg .pt{fill:#9a9a9a;fill-opacity:.75}svg .front{fill:#d62728}svg .stair{fill:none;stroke:#d62728;stroke-width:1.5}"
    ".wide{overflow-x:auto;max-width:100%}"
    "table{border-collapse:collapse;font-size:12px;margin:4px 0 12px}th,td{padding:2px 8px;border:1px solid #e3e3e3;text-align:right}"
    "th{background:#f4f4f4;font-weight:600}td.k,th.k{text-align:left}td.na{color:#999}td.err,span.err{color:#b00020}"
    "td.best{font-weight:700}code{font-size:12px}";

std::string header_section(const Sweep& s) {
  std::string h = fmt::format("<h1>vtsim sweep: {}</h1>\n", html_escape(s.name.empty() ? "(unnamed)" : s.name));
  h += fmt::format("<p>spec hash <code>{}</code> · {} × {} = {} · <b>{}</b> failed</p>\n", html_escape(s.hash),
                   count_of(s.configs.size(), "config"), count_of(s.traces.size(), "trace"),
                   count_of(s.configs.size() * s.traces.size(), "row"), count_of(s.failed.size(), "row"));
  if (!s.failed.empty()) {
    h += "<h2>Failed rows</h2>\n<p class=\"note\">Failed rows have no values: a config's mean over traces needs every trace, "
         "so a failure makes that config's means n/a.</p>\n<table class=\"failed\"><tr><th>row</th><th class=\"k\">config</th>"
         "<th class=\"k\">trace</th><th class=\"k\">error</th></tr>\n";
    for (const json* row : s.failed) {
      const auto c = index_of(field(*row, "config")), t = index_of(field(*row, "trace"));
      h += fmt::format("<tr><td>{}</td><td class=\"k\">{}</td><td class=\"k\">{}</td><td class=\"k err\">{}</td></tr>\n",
                       html_escape(text_of(field(*row, "row"))), c ? fmt::format("#{} {}", *c, html_escape(config_values_text(s, *c))) : "?",
                       t ? html_escape(trace_short(s, *t)) : "?", html_escape(row_error(*row)));
    }
    h += "</table>\n";
  }
  h += "<h2>Configs and traces</h2>\n<div class=\"wide\"><table class=\"configs\"><tr><th>config</th>";
  for (const std::string& k : s.keys) h += fmt::format("<th class=\"k\">{}</th>", html_escape(k));
  std::vector<std::string> cost_keys;
  for (const Config& c : s.configs)
    if (c.cost.is_object())
      for (const auto& kv : c.cost.items())
        if (std::find(cost_keys.begin(), cost_keys.end(), kv.key()) == cost_keys.end()) cost_keys.push_back(kv.key());
  for (const std::string& k : cost_keys) h += fmt::format("<th>cost: {}</th>", html_escape(k));
  h += "</tr>\n";
  for (std::size_t c = 0; c < s.configs.size(); ++c) {
    h += fmt::format("<tr><td>#{}</td>", c);
    for (const std::string& k : s.keys) h += fmt::format("<td class=\"k\">{}</td>", html_escape(config_value(s, c, k)));
    for (const std::string& k : cost_keys) {
      const Opt v = metric_at(s.configs[c].cost, k);
      h += fmt::format("<td>{}</td>", v && *v == 0 && k.rfind("upload_", 0) == 0 ? "no limit" : html_escape(fmt3(v)));
    }
    h += "</tr>\n";
  }
  h += "</table></div>\n<table class=\"traces\"><tr><th>trace</th><th class=\"k\">name</th><th class=\"k\">source</th></tr>\n";
  for (std::size_t t = 0; t < s.traces.size(); ++t)
    h += fmt::format("<tr><td>{}</td><td class=\"k\">{}</td><td class=\"k\">{}</td></tr>\n", t, html_escape(s.traces[t].name),
                     html_escape(s.traces[t].source));
  return h + "</table>\n";
}

std::string metric_subtitle(const Sweep& s, const std::string& metric, const char* what = "y") {
  const std::string unit = unit_of(metric);
  return fmt::format("{}: mean over {}{}{} · {}", what, count_of(s.traces.size(), "trace"), unit.empty() ? "" : ", ", unit,
                     direction_text(direction(metric)));
}

// The configs of one axis chart: grouped by their values on every other key (a group is a line),
// and within a group by the slot of their value on this axis.
struct AxisGroups {
  std::vector<std::string> other_keys;
  std::vector<std::string> labels;                          // per group
  std::vector<std::vector<std::vector<std::size_t>>> at;   // [group][slot] -> configs
};

AxisGroups group_configs(const Sweep& s, const Axis& ax) {
  AxisGroups g;
  for (const std::string& k : s.keys)
    if (k != ax.key) g.other_keys.push_back(k);
  std::map<std::vector<std::string>, std::size_t> index;
  for (std::size_t c = 0; c < s.configs.size(); ++c) {
    const auto it = s.configs[c].values.find(ax.key);
    if (it == s.configs[c].values.end()) continue;
    const auto slot = std::find(ax.values.begin(), ax.values.end(), it->second) - ax.values.begin();
    if (static_cast<std::size_t>(slot) >= ax.values.size()) continue;
    std::vector<std::string> key;
    for (const std::string& k : g.other_keys) key.push_back(config_value(s, c, k));
    auto [pos, fresh] = index.try_emplace(key, g.labels.size());
    if (fresh) {
      std::string label;
      for (const std::string& v : key) label += (label.empty() ? "" : ", ") + v;
      g.labels.push_back(label.empty() ? "all configs" : label);
      g.at.emplace_back(ax.values.size());
    }
    g.at[pos->second][static_cast<std::size_t>(slot)].push_back(c);
  }
  return g;
}

// Chart width for a row of one chart per axis: the row fills the page (1208 px of content,
// 12 px gaps, 1 px borders), between 300 and 600 px a chart; more axes than fit wrap.
double axis_chart_width(std::size_t axes) {
  for (std::size_t n = std::max<std::size_t>(axes, 1); n > 0; --n) {
    const double w = std::floor((1208.0 - 12.0 * static_cast<double>(n - 1)) / static_cast<double>(n)) - 2;
    if (w >= 300) return std::min(w, 600.0);
  }
  return 300;
}

std::string axis_chart(const Sweep& s, const MetricData& m, const Axis& ax) {
  const double W = axis_chart_width(s.axes.size());
  const AxisGroups g = group_configs(s, ax);
  std::vector<Line> lines;
  for (std::size_t k = 0; k < g.labels.size(); ++k) {
    Line l{g.labels[k], {}};
    for (const auto& configs : g.at[k]) {
      double sum = 0;
      std::size_t n = 0;
      for (std::size_t c : configs)
        if (m.mean[c]) sum += *m.mean[c], ++n;
      l.y.push_back(n ? Opt(sum / static_cast<double>(n)) : std::nullopt);
    }
    lines.push_back(std::move(l));
  }
  const bool banded = lines.size() > kMaxLines;
  std::string legend_heading;
  for (const std::string& k : g.other_keys)
    legend_heading += (legend_heading.empty() ? (banded ? "over the combinations of " : "lines: ") : ", ") + k;
  const std::string title = fmt::format("{} over {}", m.path, ax.key);
  const XSlots xs = axis_slots(ax);
  if (!banded) return line_chart(title, metric_subtitle(s, m.path), xs, lines, nullptr, legend_heading, W);
  Band band{{}, {}, {}, lines.size()};
  for (std::size_t slot = 0; slot < ax.values.size(); ++slot) {
    std::vector<double> v;
    for (const Line& l : lines)
      if (l.y[slot]) v.push_back(*l.y[slot]);
    const bool any = !v.empty();
    band.lo.push_back(any ? Opt(*std::min_element(v.begin(), v.end())) : std::nullopt);
    band.hi.push_back(any ? Opt(*std::max_element(v.begin(), v.end())) : std::nullopt);
    double sum = 0;
    for (double a : v) sum += a;
    band.mid.push_back(any ? Opt(sum / static_cast<double>(v.size())) : std::nullopt);
  }
  return line_chart(title, metric_subtitle(s, m.path), xs, lines, &band, legend_heading, W);
}

std::string axes_section(const Sweep& s, const std::vector<MetricData>& data) {
  std::string h = "<h2>Metrics over the axes</h2>\n";
  if (s.axes.empty()) {
    h += "<p class=\"note\">The spec lists its configs (no grid axes): one bar per config, the mean over traces.</p>\n";
  } else {
    h += "<p class=\"note\">One chart per metric and axis: y is the metric's mean over the traces, one line per combination of "
         "the other keys' values (more than six: their mean with a min–max band). A config failing on any trace is left out.</p>\n";
  }
  for (const MetricData& m : data) {
    h += fmt::format("<h3 id=\"axes-{0}\">{0}</h3>\n<div class=\"charts\">\n", html_escape(m.path));
    if (std::none_of(m.mean.begin(), m.mean.end(), [](const Opt& v) { return v.has_value(); })) {
      h += "<p class=\"note\">n/a for every config.</p></div>\n";
      continue;
    }
    if (s.axes.empty()) {
      std::vector<std::pair<std::string, Opt>> bars;
      for (std::size_t c = 0; c < s.configs.size(); ++c) {
        std::string vals;
        for (const std::string& k : s.keys) vals += (vals.empty() ? ": " : ", ") + config_value(s, c, k);
        bars.emplace_back(fmt::format("#{}{}", c, vals), m.mean[c]);
      }
      h += bar_chart(m.path, metric_subtitle(s, m.path, "bars"), bars);
    }
    for (const Axis& ax : s.axes) h += axis_chart(s, m, ax);
    h += "</div>\n";
  }
  return h;
}

// Background of a cell from its place between its column's best and worst: green to red when a
// direction is better, light to dark blue when none is.
std::string cell_style(double v, double lo, double hi, int dir) {
  if (!(hi > lo) || dir == 0) return "";  // no direction: no colour (neither end is better)
  const double t = (v - lo) / (hi - lo);
  const double good = dir < 0 ? 1 - t : t;
  return fmt::format(" style=\"background:hsl({:.0f},65%,84%)\"", 120 * good);
}

std::string breakdown_table(const Sweep& s, const MetricData& m) {
  const int dir = direction(m.path);
  std::string h = fmt::format("<h3 id=\"trace-{0}\">{0}</h3>\n<p class=\"note\">{1}{2}; each column coloured on its own "
                              "(configs compared on one trace){3}.</p>\n<div class=\"wide\"><table class=\"breakdown\" data-metric=\"{0}\"><tr><th>config</th>",
                              html_escape(m.path), direction_text(dir), unit_of(m.path).empty() ? "" : ", " + unit_of(m.path),
                              dir ? ": green best, red worst, bold the best" : ": not coloured");
  for (const std::string& k : s.keys) h += fmt::format("<th class=\"k\">{}</th>", html_escape(k));
  for (std::size_t t = 0; t < s.traces.size(); ++t)
    h += fmt::format("<th title=\"{}\">{}</th>", html_escape(s.traces[t].name), html_escape(trace_short(s, t)));
  h += "<th>mean</th></tr>\n";
  // Columns: the traces, then the mean.
  const std::size_t cols = s.traces.size() + 1;
  auto value = [&](std::size_t c, std::size_t col) { return col < s.traces.size() ? m.cell[c][col] : m.mean[c]; };
  std::vector<double> lo(cols, kInf), hi(cols, -kInf);
  for (std::size_t c = 0; c < s.configs.size(); ++c)
    for (std::size_t col = 0; col < cols; ++col)
      if (const Opt v = value(c, col)) lo[col] = std::min(lo[col], *v), hi[col] = std::max(hi[col], *v);
  for (std::size_t c = 0; c < s.configs.size(); ++c) {
    h += fmt::format("<tr><td>#{}</td>", c);
    for (const std::string& k : s.keys) h += fmt::format("<td class=\"k\">{}</td>", html_escape(config_value(s, c, k)));
    for (std::size_t col = 0; col < cols; ++col) {
      const json* row = col < s.traces.size() ? s.row_at[c][col] : nullptr;
      if (row && !row_ok(row)) {
        h += fmt::format("<td class=\"err\" title=\"{}\">error</td>", html_escape(row_error(*row)));
        continue;
      }
      const Opt v = value(c, col);
      if (!v) {
        h += "<td class=\"na\">n/a</td>";
        continue;
      }
      const bool best = dir != 0 && hi[col] > lo[col] && *v == (dir < 0 ? lo[col] : hi[col]);
      h += fmt::format("<td{}{}>{}</td>", best ? " class=\"best\"" : "", cell_style(*v, lo[col], hi[col], dir), fmt3(*v));
    }
    h += "</tr>\n";
  }
  return h + "</table></div>\n";
}

struct CostDef {
  const char* key;
  const char* title;
  bool zero_unlimited;  // the sweep writes 0 for "no limit"
  const char* metric;   // from the summary (mean over traces) instead of the config's cost
};

const CostDef kCosts[] = {
    {"pool_MiB", "VT page pool, MiB", false, nullptr},
    {"ram_MiB", "RAM cache, MiB", false, nullptr},
    {"upload_tiles_per_frame", "upload budget, tiles/frame", true, nullptr},
    {"upload_MiB_per_frame", "upload budget, MiB/frame", true, nullptr},
    {"disk_MBps", "disk read, MB/s (mean over traces)", false, "bandwidth.disk_read_MBps"},
};

const char* const kPopins[] = {"popin.blurry_fraction_mean", "popin.time_to_sharp_s.mean"};

std::vector<Opt> cost_values(const Sweep& s, const CostDef& cd) {
  if (cd.metric) return gather(s, cd.metric).mean;
  std::vector<Opt> out;
  for (const Config& c : s.configs) {
    Opt v = metric_at(c.cost, cd.key);
    if (v && cd.zero_unlimited && *v == 0) v = kInf;
    out.push_back(v);
  }
  return out;
}

std::string front_table(const Sweep& s, const std::vector<Point>& pts, const std::vector<std::size_t>& front, const char* popin,
                        const CostDef& cd) {
  std::string h = fmt::format("<table class=\"front\" data-popin=\"{}\" data-cost=\"{}\"><tr><th>front</th>", popin, cd.key);
  for (const std::string& k : s.keys) h += fmt::format("<th class=\"k\">{}</th>", html_escape(k));
  h += fmt::format("<th>{}</th><th>{}</th></tr>\n", cd.key, popin);
  for (std::size_t k : front) {
    const Point& p = pts[k];
    h += fmt::format("<tr data-config=\"{0}\"><td>#{0}</td>", p.config);
    for (const std::string& key : s.keys) h += fmt::format("<td class=\"k\">{}</td>", html_escape(config_value(s, p.config, key)));
    h += fmt::format("<td>{}</td><td>{}</td></tr>\n", std::isinf(p.x) ? "no limit" : fmt3(p.x), fmt3(p.y));
  }
  return h + "</table>\n";
}

std::string pareto_section(const Sweep& s) {
  // Only configs that meet the blur bound compete: a config that saves cost by leaving the screen
  // blurry is not a trade-off (a 65 %-blurry config led the time-to-sharp front: blur that never
  // clears has no cut to recover from).
  const MetricData blur = gather(s, "popin.blurry_fraction_mean");
  std::vector<bool> meets(s.configs.size(), false);
  std::size_t n_meet = 0;
  for (std::size_t c = 0; c < s.configs.size(); ++c)
    if (blur.mean[c] && *blur.mean[c] <= s.blur_bound) meets[c] = true, ++n_meet;
  std::string h = fmt::format(
      "<h2>Pop-in against cost: the Pareto front</h2>\n<p class=\"note\">Each point is a config (its mean over the "
      "traces) whose mean blurry fraction is at most <b>{}</b> (the spec's <code>blur_bound</code>): <b>{} of {}</b> configs "
      "meet it, the others are left out. Red: the configs no other config beats on both cost and pop-in, joined as a "
      "staircase. A cost equal for every config is left out; an upload budget of 0 means no limit.</p>\n",
      fmt3(s.blur_bound), n_meet, s.configs.size());
  std::string charts;
  for (const char* popin : kPopins) {
    const MetricData pm = gather(s, popin);
    for (const CostDef& cd : kCosts) {
      const std::vector<Opt> cost = cost_values(s, cd);
      std::vector<Point> pts;
      std::vector<std::pair<double, double>> xy;
      for (std::size_t c = 0; c < s.configs.size(); ++c)
        if (meets[c] && cost[c] && pm.mean[c]) {
          pts.push_back({c, *cost[c], *pm.mean[c]});
          xy.emplace_back(*cost[c], *pm.mean[c]);
        }
      const bool varies = std::any_of(pts.begin(), pts.end(), [&](const Point& p) { return p.x != pts.front().x; });
      if (!varies) continue;
      const std::vector<std::size_t> front = pareto_front(xy);
      const std::size_t left_out = n_meet - pts.size();
      const std::string sub = fmt::format("y: {}, mean over traces · lower-left is better{}", unit_of(popin),
                                          left_out ? fmt::format(" · n/a: {} of {} configs", left_out, n_meet) : "");
      charts += fmt::format("<h3>{} against {}</h3>\n<div class=\"pair\">\n", popin, cd.title);
      charts += pareto_chart(fmt::format("{} vs {}", popin, cd.key), sub, cd.title, pts, front);
      charts += "<div class=\"wide\">" + front_table(s, pts, front, popin, cd) + "</div>\n</div>\n";
    }
  }
  return h + (charts.empty() ? "<p class=\"note\">No cost varies across the configs that meet the blur bound (or pop-in is "
                               "n/a): no front to draw.</p>\n"
                             : charts);
}

}  // namespace vtsim::sweep_report_detail

namespace vtsim {

std::vector<std::size_t> pareto_front(const std::vector<std::pair<double, double>>& points) {
  std::vector<std::size_t> order;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!std::isnan(points[i].first) && !std::isnan(points[i].second)) order.push_back(i);
  // By x, then y, then index: a point is on the front iff its y is below every y before it, so an
  // equal point after the first, and anything no better in y than a cheaper point, drops out.
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::tie(points[a].first, points[a].second, a) < std::tie(points[b].first, points[b].second, b);
  });
  std::vector<std::size_t> front;
  double best_y = std::numeric_limits<double>::infinity();
  for (std::size_t i : order)
    if (points[i].second < best_y || front.empty()) {
      front.push_back(i);
      best_y = points[i].second;
    }
  return front;
}

namespace {

// metrics.opt rows: per trace, the VT pool's LRU miss-ratio curve (from the trace's first row that
// recorded one) beside each config's live pool miss ratio at its own pool size, so the curve's
// prediction and the pipeline's measurement share one chart (docs/cache.md, "Curves in reports").
// A string member of a JSON object, or "" (find and get_ptr: GCC 12 -O3 reports value()'s
// null check as a possible null dereference).
std::string mrc_str(const nlohmann::json& j, const char* key) {
  if (!j.is_object()) return {};
  const auto it = j.find(key);
  if (it == j.end()) return {};
  const auto* p = it->get_ptr<const std::string*>();
  return p ? *p : std::string();
}

std::string sweep_mrc_section(const nlohmann::json& meta, const std::vector<nlohmann::json>& rows) {
  std::string h;
  if (!meta.is_object() || !meta.contains("traces") || !meta["traces"].is_array()) return h;
  for (std::size_t t = 0; t < meta["traces"].size(); ++t) try {
    const nlohmann::json* curve = nullptr;
    std::map<std::uint64_t, std::pair<double, double>> live;  // pool pages -> (misses, accesses), summed
    for (const nlohmann::json& r : rows) {
      if (!r.is_object() || !r.contains("trace") || r["trace"] != t || mrc_str(r, "status") != "ok" ||
          !r.contains("summary") || !r["summary"].is_object())
        continue;
      const nlohmann::json* pool = summary_path(r["summary"], "vt.pool");
      if (pool == nullptr || !pool->is_object() || !pool->contains("bounds")) continue;
      // .at() throughout: a key missing from a row not written by vtsim throws, and the trace is skipped
      if (curve == nullptr) curve = &pool->at("bounds").at("mrc");
      const auto pages = r.at("summary").at("vt").at("pool_pages").get<std::uint64_t>();
      auto& [m, a] = live[pages];
      m += pool->at("misses").get<double>();
      a += pool->at("hits").get<double>() + pool->at("misses").get<double>();
    }
    if (curve == nullptr) continue;
    MissRatioCurve c;
    c.unit = MrcUnit::kPages;
    c.capacity = curve->at("capacity").get<std::vector<std::uint64_t>>();
    c.miss_ratio = curve->at("miss_ratio").get<std::vector<double>>();
    if (c.capacity.size() != c.miss_ratio.size()) continue;
    // The knee the run found on its fine grid (mrc.h: 1025 capacities), not one on these points.
    if (curve->contains("knee") && curve->at("knee").is_object()) {
      c.knee.found = true;
      c.knee.capacity = curve->at("knee").at("capacity").get<std::uint64_t>();
      c.knee.miss_ratio = curve->at("knee").at("miss_ratio").get<double>();
      c.knee.index = static_cast<std::size_t>(
          std::lower_bound(c.capacity.begin(), c.capacity.end(), c.knee.capacity) - c.capacity.begin());
      if (c.knee.index >= c.capacity.size()) c.knee.index = c.capacity.size() - 1;
    }
    MissRatioCurve pts;
    pts.unit = MrcUnit::kPages;
    for (const auto& [pages, ma] : live) {
      pts.capacity.push_back(pages);
      pts.miss_ratio.push_back(ma.second > 0 ? ma.first / ma.second : 0.0);
    }
    if (h.empty())
      h = "<h2>VT pool: miss-ratio curves</h2>\n<p class=\"note\">The LRU curve of each trace's recorded pool "
          "accesses (metrics.opt; its first config's run), and the live pool miss ratio each pool size gave, "
          "averaged over the configs of that size: where the pipeline's timing and throttling part from the curve.</p>\n";
    h += mrc_chart_svg({{"LRU curve (offline)", c}, {"live pool, per size", pts}},
                       "Pool miss ratio: " + (mrc_str(meta["traces"][t], "name").empty() ? "trace " + std::to_string(t) : mrc_str(meta["traces"][t], "name")));
  } catch (const nlohmann::json::exception&) {
    continue;  // a row or meta not as `vtsim sweep` writes them: no curve for that trace, as n/a elsewhere
  } catch (const std::invalid_argument&) {
    continue;  // mrc_chart_svg: curves of mixed units
  }
  return h;
}

}  // namespace

std::string sweep_report_html(const nlohmann::json& meta, const std::vector<nlohmann::json>& rows) {
  using namespace sweep_report_detail;
  const Sweep s = load_sweep(meta, rows);
  std::vector<MetricData> data;
  for (const std::string& m : s.metrics) data.push_back(gather(s, m));
  std::string h = fmt::format("<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                              "<title>vtsim sweep: {}</title>\n<style>{}</style></head><body>\n",
                              html_escape(s.name), kStyle);
  h += header_section(s);
  h += axes_section(s, data);
  h += "<h2>Per trace</h2>\n";
  for (const MetricData& m : data) h += breakdown_table(s, m);
  h += pareto_section(s);
  h += sweep_mrc_section(meta, rows);
  return h + "</body></html>\n";
}

}  // namespace vtsim
