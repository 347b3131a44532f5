#pragma once
// The replay report's tile waterfall (docs/report.md, "The replay report"): the tiles one frame
// was waiting for, one row each, their stages as horizontal bars on a shared time axis — queue,
// read, decode wait, decode, upload wait, upload — and a mark where each was first sampled, like a
// browser's network panel. Inline SVG in the style of svg_chart.h (the same text classes, sizes
// and legend), checked by tests/browser/report_browser.sh like the other charts. Pure; thread-safe.
#include <string>
#include <vector>

namespace vtsim {

// Stages a waterfall bar may show, in pipeline order (the legend's order and colours).
enum class WaterfallStage { queue, read, decode_wait, decode, upload_wait, upload, unserved, count };
const char* waterfall_stage_name(WaterfallStage s);

struct WaterfallBar {
  WaterfallStage stage = WaterfallStage::queue;
  double t0_ms = 0, t1_ms = 0;  // relative to the frame's start
};

struct WaterfallRow {
  std::string label;               // the tile
  std::string note;                // its tooltip: request frame, latency, outcome
  std::vector<WaterfallBar> bars;
  double sampled_ms = 0;           // first sampled, relative to the frame's start
  bool sampled = false;
};

struct Waterfall {
  std::string title, subtitle;
  std::vector<WaterfallRow> rows;  // top to bottom
  std::size_t more = 0;            // rows left out (shown as a note)
  double frame_ms = 16.667;        // the frame's length: the frame band drawn at [0, frame_ms)
};

// The chart, `width` px wide; a waterfall without rows says so in one line.
std::string waterfall_svg(const Waterfall& w, double width = 620);

class TimelineRecorder;
// The measured frame at or after `from` (the start-up fill's end: the report passes the first
// sharp frame) that the recorder saw with the largest blurry fraction, the earliest of equals;
// -1 when none was measured.
int worst_frame(const TimelineRecorder& tl, int from = 0);
// The tiles frame `frame` was waiting for: requested at or before its start and not uploaded
// before it (nor ended unserved), the earliest requests first, at most `max_rows` of them. Times
// in ms from the frame's start. `what` heads the title ("the most blurry frame").
Waterfall frame_waterfall(const TimelineRecorder& tl, int frame, const std::string& what, std::size_t max_rows = 40);

}  // namespace vtsim
