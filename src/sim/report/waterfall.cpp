#include "sim/report/waterfall.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "sim/report/html_escape.h"
#include "sim/report/svg_chart.h"
#include "sim/run/timeline.h"

namespace vtsim {

namespace {

constexpr double kWfSmallPx = 11, kWfTitlePx = 13;
constexpr const char* kWfColour[] = {"#c7c7c7", "#1f77b4", "#aec7e8", "#2ca02c", "#ffbb78", "#ff7f0e", "#9467bd"};
constexpr const char* kWfSampled = "#d62728";

// A text element, cut with an ellipsis to max_w (the whole text in a tooltip), as svg_chart's.
std::string wf_text(double x, double y, const std::string& s, const char* cls, const char* anchor, double max_w) {
  const double px = std::string_view(cls) == "title" ? kWfTitlePx : kWfSmallPx;
  const double scale = std::string_view(cls) == "title" ? 1.1 : 1.0;
  if (chart_text_width(s, px) * scale <= max_w)
    return fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"{}\" text-anchor=\"{}\">{}</text>\n", x, y, cls, anchor, html_escape(s));
  std::string t = s;
  while (!t.empty() && chart_text_width(t + "…", px) * scale > max_w) {
    t.pop_back();
    while (!t.empty() && (static_cast<unsigned char>(t.back()) & 0xC0) == 0x80) t.pop_back();
    if (!t.empty() && static_cast<unsigned char>(t.back()) >= 0xC0) t.pop_back();
  }
  return fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" class=\"{}\" text-anchor=\"{}\"><title>{}</title>{}…</text>\n", x, y, cls,
                     anchor, html_escape(s), html_escape(t));
}

const char* wf_unserved(Unserved w) {
  switch (w) {
    case Unserved::cancelled: return "cancelled";
    case Unserved::failed: return "failed";
    case Unserved::open_at_end: return "open at the end";
    case Unserved::stale: return "stale";
  }
  return "?";
}

std::string wf_ms(double v) { return std::fabs(v) >= 100 ? fmt::format("{:.0f} ms", v) : fmt::format("{:.1f} ms", v); }

}  // namespace

const char* waterfall_stage_name(WaterfallStage s) {
  switch (s) {
    case WaterfallStage::queue: return "queue";
    case WaterfallStage::read: return "read";
    case WaterfallStage::decode_wait: return "decode wait";
    case WaterfallStage::decode: return "decode";
    case WaterfallStage::upload_wait: return "upload wait";
    case WaterfallStage::upload: return "upload";
    case WaterfallStage::unserved: return "ended unserved";
    case WaterfallStage::count: break;
  }
  return "?";
}

std::string waterfall_svg(const Waterfall& w, double W) {
  constexpr double T = 46, RowH = 14, R = 10;
  double label_w = 0;
  for (const WaterfallRow& r : w.rows) label_w = std::max(label_w, chart_text_width(r.label, kWfSmallPx));
  label_w = std::min(label_w + 4, W * 0.3);
  const double L = 8 + label_w + 6, PW = W - L - R;
  // The time axis: every bar and mark, and the frame itself.
  double lo = 0, hi = w.frame_ms;
  for (const WaterfallRow& r : w.rows) {
    for (const WaterfallBar& b : r.bars) {
      lo = std::min(lo, b.t0_ms);
      hi = std::max(hi, b.t1_ms);
    }
    if (r.sampled) hi = std::max(hi, r.sampled_ms + w.frame_ms);
  }
  const ChartScale sc = nice_scale(lo, hi, 5);
  const auto X = [&](double v) { return L + std::clamp((v - sc.lo) / (sc.hi - sc.lo), 0.0, 1.0) * PW; };
  const double PH = RowH * static_cast<double>(std::max<std::size_t>(1, w.rows.size()));
  std::string body;
  for (double v : sc.ticks)
    body += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"grid\"/>\n", X(v), X(v), T, T + PH);
  // The frame: a band from its start to its end.
  body += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" fill=\"#fde9e9\"><title>the frame: 0 to {}</title></rect>\n",
                      X(0), T, std::max(1.0, X(w.frame_ms) - X(0)), PH, wf_ms(w.frame_ms));
  double last_r = -1e9;
  for (double v : sc.ticks) {
    const std::string label = format_tick(v, sc.step);
    const double tw = chart_text_width(label, kWfSmallPx);
    if (X(v) - tw / 2 < last_r + 8 || X(v) + tw / 2 > W - 2 || X(v) - tw / 2 < 2) continue;
    last_r = X(v) + tw / 2;
    body += wf_text(X(v), T + PH + 14, label, "tick", "middle", W);
  }
  if (w.rows.empty())
    body += wf_text(L, T + RowH - 3, "no tile was on its way at this frame", "tick", "start", PW);
  for (std::size_t i = 0; i < w.rows.size(); ++i) {
    const WaterfallRow& r = w.rows[i];
    const double y = T + RowH * static_cast<double>(i);
    body += wf_text(L - 6, y + RowH - 3, r.label, "tick", "end", label_w);
    for (const WaterfallBar& b : r.bars) {
      const auto s = static_cast<std::size_t>(b.stage);
      body += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" fill=\"{}\"><title>{}: {}: {} "
                          "({} to {})</title></rect>\n",
                          X(b.t0_ms), y + 2, std::max(1.0, X(b.t1_ms) - X(b.t0_ms)), RowH - 4, kWfColour[s], html_escape(r.label),
                          waterfall_stage_name(b.stage), wf_ms(b.t1_ms - b.t0_ms), wf_ms(b.t0_ms), wf_ms(b.t1_ms));
    }
    if (r.sampled)
      body += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"3\" height=\"{:.1f}\" fill=\"{}\"><title>{}: first sampled at {}; {}</title></rect>\n",
                          X(r.sampled_ms) - 1.5, y + 1, RowH - 2, kWfSampled, html_escape(r.label), wf_ms(r.sampled_ms),
                          html_escape(r.note));
  }
  double y_more = T + PH + 20;
  if (w.more > 0) {
    body += wf_text(8, y_more + 11, fmt::format("… and {} more tile{} not shown", w.more, w.more == 1 ? "" : "s"), "sub", "start", W - 16);
    y_more += 16;
  }
  // The legend, as svg_chart's: swatches flowing left to right, wrapping at the width.
  std::string lg;
  double x = 8, ly = y_more + 13;
  const auto swatch = [&](const std::string& label, const char* colour, double sw) {
    const double tw = chart_text_width(label, kWfSmallPx);
    if (x > 8 && x + 18 + tw > W - 8) {
      x = 8;
      ly += 16;
    }
    lg += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.0f}\" height=\"9\" fill=\"{}\"/>\n", x, ly - 9, sw, colour);
    lg += wf_text(x + 18, ly, label, "lgd", "start", W - 28);
    x += 18 + tw + 16;
  };
  for (std::size_t s = 0; s < static_cast<std::size_t>(WaterfallStage::count); ++s)
    swatch(waterfall_stage_name(static_cast<WaterfallStage>(s)), kWfColour[s], 12);
  swatch("first sampled", kWfSampled, 3);
  swatch("the frame", "#fde9e9", 12);
  const double h = ly + 8;
  std::string o = fmt::format("<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"chart\" width=\"{:.0f}\" height=\"{:.0f}\" "
                              "viewBox=\"0 0 {:.0f} {:.0f}\" role=\"img\" aria-label=\"{}\">\n",
                              W, h, W, h, html_escape(w.title));
  o += wf_text(8, 18, w.title, "title", "start", W - 16);
  o += wf_text(8, 34, w.subtitle, "sub", "start", W - 16);
  return o + body + lg + "</svg>\n";
}

int worst_frame(const TimelineRecorder& tl, int from) {
  int worst = -1;
  double blur = -1.0;
  for (const TimelineRecorder::FrameMark& f : tl.frames())
    if (f.measured && f.frame >= from && f.blurry > blur) {
      blur = f.blurry;
      worst = f.frame;
    }
  return worst;
}

Waterfall frame_waterfall(const TimelineRecorder& tl, int frame, const std::string& what, std::size_t max_rows) {
  Waterfall w;
  w.frame_ms = tl.period_s() * 1e3;
  const auto& frames = tl.frames();
  const auto it = std::find_if(frames.begin(), frames.end(), [&](const TimelineRecorder::FrameMark& f) { return f.frame == frame; });
  if (it == frames.end()) {
    w.title = fmt::format("Tiles of frame {}: not in the timeline", frame);
    w.subtitle = "the frame is outside the run or --timeline-frames";
    return w;
  }
  const Ticks t0 = it->start;
  const auto ms = [t0](Ticks t) { return ticks_to_ms(t - t0); };
  std::vector<const TileLife*> on_way;
  for (const TileLife& l : tl.lives()) {
    if (l.request > t0) break;  // lives are in request order
    if (l.upload_start >= 0 && l.upload_start < t0) continue;                       // resident before the frame
    if (l.upload_start < 0 && l.ended >= 0 && l.ended < t0) continue;               // gone unserved before it
    on_way.push_back(&l);
  }
  w.title = fmt::format("Tiles of frame {} ({}{}): {} on their way", frame, what,
                        it->measured ? fmt::format(", {:.1f} % blurry", 100.0 * it->blurry) : std::string(), on_way.size());
  w.subtitle = "each row a tile requested by then and not yet uploaded; ms from the frame's start; red: first sampled";
  if (on_way.size() > max_rows) {
    w.more = on_way.size() - max_rows;
    on_way.resize(max_rows);
  }
  for (const TileLife* l : on_way) {
    WaterfallRow r;
    r.label = fmt::format("l{} ({},{}){}", l->key.level(), l->key.x(), l->key.y(), l->key.layer() ? fmt::format(" L{}", l->key.layer()) : "");
    const auto bar = [&](WaterfallStage s, Ticks a, Ticks b) {
      if (a >= 0 && b >= a) r.bars.push_back({s, ms(a), ms(b)});
    };
    const Ticks q_end = l->ram_hit ? l->request : (l->produced ? l->decode_start : l->read_start);
    if (!l->ram_hit) bar(WaterfallStage::queue, l->request, q_end >= 0 ? q_end : l->ended);
    if (!l->ram_hit && !l->produced && l->read_start >= 0) {
      bar(WaterfallStage::read, std::max(l->request, l->read_start), std::max(l->request, l->read_end));
      bar(WaterfallStage::decode_wait, l->read_end, l->decode_start);
    }
    if (!l->ram_hit && l->decode_start >= 0) bar(WaterfallStage::decode, l->decode_start, l->decode_end);
    if (l->in_ram >= 0) bar(WaterfallStage::upload_wait, l->in_ram, l->upload_start >= 0 ? l->upload_start : l->ended);
    if (l->upload_start >= 0) bar(WaterfallStage::upload, l->upload_start, std::max(l->upload_end, l->upload_start));
    if (l->upload_start < 0 && l->ended >= 0) bar(WaterfallStage::unserved, l->ended, l->ended);
    r.sampled = l->sampled >= 0;
    if (r.sampled) r.sampled_ms = ms(l->sampled);
    r.note = fmt::format("requested at frame {}{}{}", l->frame, l->ram_hit ? " (RAM hit)" : "",
                         r.sampled ? fmt::format(", sampled {:.1f} ms later", ticks_to_ms(l->sampled - l->request))
                         : l->ended >= 0 ? fmt::format(", ended {}", wf_unserved(l->why))
                                         : std::string(", never sampled"));
    w.rows.push_back(std::move(r));
  }
  return w;
}

}  // namespace vtsim
