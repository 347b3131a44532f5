#pragma once
// Inline SVG charts for the HTML reports (replay --report, vtsim report): a line chart over time
// and a grouped horizontal bar chart, self-contained (no scripts, no external files). Layout rules
// that a browser test checks (tests/browser/report_browser.sh): the title and subtitle sit on
// their own lines at the top, the legend below the plot, about four y intervals over a 150 px
// plot (~30 px apart, 11 px text), x tick labels that would collide dropped, and every text cut to
// fit inside its chart (the whole text in a tooltip).
// Scales: robust_scale() in docs/report.md ("Scales"). Pure functions; thread-safe.
#include <string>
#include <string_view>
#include <vector>

namespace vtsim {

// A linear axis: [lo, hi] with round ticks (1, 2, 2.5 or 5 × 10^k apart), and whether the data
// went above hi (then `max` is the largest value, drawn at the top edge and noted).
struct ChartScale {
  double lo = 0, hi = 1;
  double step = 0.25;
  std::vector<double> ticks;
  bool clipped = false;
  double max = 0;  // the largest data value, clipped or not
};

// A scale over [lo, hi] with about `target` intervals, widened to round ticks.
ChartScale nice_scale(double lo, double hi, int target = 4);

// The scale the report uses for a series: from 0 when all values are >= 0; its top is the data's
// maximum unless that exceeds 2× the 95th percentile (nearest rank): then the top is 1.25× that
// percentile and `clipped` is set — a start-up spike or a cut then no longer flattens the steady
// state to a line at 0 (issue 26 §3: 3.8 MB/s on a 0–500 axis).
ChartScale robust_scale(std::vector<double> values);

// A tick value with as many decimals as the step needs (0.25 -> "0.25", 20 -> "20"), never in
// exponent form for values between 1e-4 and 1e9.
std::string format_tick(double v, double step);

// An estimate of a text's rendered width in px at font size px, on the wide side (DejaVu Sans
// metrics): layout decided on it leaves room rather than overlaps.
double chart_text_width(std::string_view s, double px);

struct ChartLine {
  std::string label;
  std::string colour;
  std::vector<double> y;  // one per x
  bool step = false;      // a staircase (levels, counts) rather than a slope
  bool dashed = false;    // a reference (a budget, a capacity)
};

struct TimeChart {
  std::string title, subtitle;
  std::string y_unit;  // shown in the subtitle line's end ("MB/s")
  std::string x_unit = "s";
  std::vector<double> x;  // ascending
  std::vector<ChartLine> lines;
  std::vector<double> marks;  // x positions drawn as dashed vertical lines (cuts, turns)
  std::string marks_label;    // legend text of the marks ("cut / fast turn"); empty: no entry
  bool robust = true;         // robust_scale() on y; false: the full range
  double y_max_hint = 0;      // when > 0, the y range reaches at least this (a fraction's 100 %)
};

// A line chart `width` px wide; at most ~1200 points per line (each bucket's minimum and maximum
// are both kept, so spikes survive the downsampling).
std::string time_chart_svg(const TimeChart& c, double width = 620);

struct BarSeries {
  std::string label, colour;
  std::vector<double> v;  // one per group; NaN: no bar
};

// Horizontal bars: one row of bars per group label, one bar per series in each row, values
// printed at the bar ends; the scale is robust_scale() of every value.
std::string bar_chart_svg(const std::string& title, const std::string& subtitle, const std::vector<std::string>& groups,
                          const std::vector<BarSeries>& series, double width = 620);

// The palette every chart uses (6 colours, colour-blind distinguishable pairs).
const char* chart_colour(std::size_t i);

// The pieces every chart of the report room (replay, runs, sweep, miss-ratio curves) draws with.
// Every SVG text uses these sizes (the reports' CSS sets the same); widths are estimated from them.
inline constexpr double kChartTitlePx = 13, kChartSmallPx = 11;

// s cut to fit max_w at px (chart_text_width), ending in an ellipsis; whole UTF-8 characters only.
std::string chart_text_cut(std::string_view s, double px, double max_w);

// The opening <svg> tag of a chart w × h px, labelled for screen readers.
std::string chart_svg_open(double w, double h, const std::string& label);

// How a text estimated wider than its room fits: `cut` with an ellipsis at its own size; or
// `shrink` to a smaller font (down to 3/4 of px, set in a style attribute) and only then cut.
// Either way a cut text carries the whole in a tooltip.
enum class ChartTextFit { cut, shrink };

// A <text> element at (x, y) of class cls ("title" is bold: 10 % wider) and anchor, at most max_w
// px wide at font size px.
std::string chart_text_svg(double x, double y, std::string_view s, const char* cls, const char* anchor, double px,
                           double max_w, ChartTextFit fit = ChartTextFit::cut);

}  // namespace vtsim
