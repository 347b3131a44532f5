#include "sim/run/report_html.h"
#include "sim/run/report_identity.h"

#include "cache/policy/mrc.h"
#include "sim/run/mrc_chart.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace vtsim {

namespace {

struct Series {
  std::string name;
  std::string colour;
  std::vector<double> y;  // one value per x
};

std::string escape(const std::string& s) { return html_escape(s); }

// A line chart of several series over x; at most ~1200 points per series (min and max of each
// bucket are both kept, so spikes survive the downsampling). `marks` are x positions drawn as
// vertical lines (cuts, turns).
std::string chart(const std::string& title, const std::string& unit, const std::vector<double>& x,
                  const std::vector<Series>& series, const std::vector<double>& marks = {}, bool step = false) {
  constexpr double W = 900, H = 220, L = 60, R = 10, T = 28, B = 30;
  if (x.empty()) return {};
  const double x0 = x.front(), x1 = std::max(x.back(), x0 + 1e-9);
  double ymax = 0;
  for (const auto& s : series)
    for (double v : s.y) ymax = std::max(ymax, v);
  if (!(ymax > 0)) ymax = 1;
  // A round upper bound: 1, 2 or 5 times a power of ten.
  const double p = std::pow(10.0, std::floor(std::log10(ymax)));
  const double top = ymax <= p ? p : ymax <= 2 * p ? 2 * p : ymax <= 5 * p ? 5 * p : 10 * p;
  auto X = [&](double v) { return L + (v - x0) / (x1 - x0) * (W - L - R); };
  auto Y = [&](double v) { return T + (1.0 - v / top) * (H - T - B); };
  std::string o = fmt::format("<svg viewBox=\"0 0 {} {}\" width=\"{}\" height=\"{}\" class=\"chart\">\n", W, H, W, H);
  o += fmt::format("<text x=\"{}\" y=\"16\" class=\"title\">{}</text>\n", L, escape(title));
  for (int k = 0; k <= 4; ++k) {
    const double v = top * k / 4;
    o += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{:.1f}\" y2=\"{:.1f}\" class=\"grid\"/>", L, W - R, Y(v), Y(v));
    o += fmt::format("<text x=\"{}\" y=\"{:.1f}\" class=\"tick\" text-anchor=\"end\">{:.4g}</text>\n", L - 4, Y(v) + 4, v);
  }
  for (int k = 0; k <= 5; ++k) {
    const double v = x0 + (x1 - x0) * k / 5;
    o += fmt::format("<text x=\"{:.1f}\" y=\"{}\" class=\"tick\" text-anchor=\"middle\">{:.4g} s</text>", X(v), H - 10, v);
  }
  o += fmt::format("<text x=\"6\" y=\"{}\" class=\"tick\">{}</text>\n", T - 8, escape(unit));
  for (double m : marks)
    o += fmt::format("<line x1=\"{:.1f}\" x2=\"{:.1f}\" y1=\"{}\" y2=\"{}\" class=\"mark\"/>\n", X(m), X(m), T, H - B);
  const std::size_t n = x.size();
  const std::size_t buckets = std::min<std::size_t>(n, 600);
  int legend_x = static_cast<int>(L) + 250;
  for (const auto& s : series) {
    std::string pts;
    double last_y = 0;
    for (std::size_t b = 0; b < buckets; ++b) {
      const std::size_t i0 = b * n / buckets, i1 = std::max(i0 + 1, (b + 1) * n / buckets);
      std::size_t imin = i0, imax = i0;
      for (std::size_t i = i0; i < i1; ++i) {
        if (s.y[i] < s.y[imin]) imin = i;
        if (s.y[i] > s.y[imax]) imax = i;
      }
      for (std::size_t i : {std::min(imin, imax), std::max(imin, imax)}) {
        if (step && !pts.empty()) pts += fmt::format("{:.1f},{:.1f} ", X(x[i]), Y(last_y));
        pts += fmt::format("{:.1f},{:.1f} ", X(x[i]), Y(s.y[i]));
        last_y = s.y[i];
      }
    }
    o += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.2\"/>\n", pts, s.colour);
    o += fmt::format("<rect x=\"{}\" y=\"7\" width=\"10\" height=\"10\" fill=\"{}\"/><text x=\"{}\" y=\"16\" class=\"tick\">{}</text>\n",
                     legend_x, s.colour, legend_x + 14, escape(s.name));
    legend_x += 16 + 7 * static_cast<int>(s.name.size()) + 20;
  }
  o += "</svg>\n";
  return o;
}

std::string row(const std::string& k, const std::string& v) {
  return fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", escape(k), escape(v));
}

double num(const nlohmann::json& j, const char* a, const char* b = nullptr, const char* c = nullptr) {
  const nlohmann::json* p = &j;
  for (const char* k : {a, b, c}) {
    if (!k) break;
    if (!p->contains(k)) return 0.0;
    p = &(*p)[k];
  }
  return p->is_number() ? p->get<double>() : 0.0;
}

}  // namespace

std::string html_escape(std::string_view s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      case '\'': o += "&#39;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string html_report(const nlohmann::json& s, const MetricsCollector& m) {
  const auto& frames = m.frames();
  std::vector<double> t, blurry, clamp, finest, disk, upload, live;
  std::vector<double> events;
  const double fps = num(s, "trace", "fps") > 0 ? num(s, "trace", "fps") : 60.0;
  const auto window = static_cast<std::size_t>(std::max(1.0, std::round(fps / 4)));  // 0.25 s moving sum
  double dsum = 0, usum = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const FrameRow& r = frames[i];
    t.push_back(r.t_s);
    blurry.push_back(r.samples ? 100.0 * r.blurry / r.samples : 0.0);
    clamp.push_back(r.clamp);
    finest.push_back(r.finest_needed);
    dsum += static_cast<double>(r.disk_bytes);
    usum += static_cast<double>(r.upload_bytes);
    if (i >= window) {
      dsum -= static_cast<double>(frames[i - window].disk_bytes);
      usum -= static_cast<double>(frames[i - window].upload_bytes);
    }
    const double span = static_cast<double>(std::min(i + 1, window)) / fps;
    disk.push_back(dsum / span / 1e6);
    upload.push_back(usum / span / 1e6);
    live.push_back(r.live_requests);
    if (r.event) events.push_back(r.t_s);
  }
  // Latency distribution: the fraction of tiles resident within x ms (a CDF), on a log-ish grid.
  std::vector<double> lat;
  for (const auto& l : m.latencies()) lat.push_back(ticks_to_ms(l.total));
  std::sort(lat.begin(), lat.end());

  std::string h = "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>vtsim replay report</title>\n<style>"
                  "body{font:14px system-ui,sans-serif;margin:24px;max-width:960px;color:#222}"
                  "table{border-collapse:collapse;margin:8px 0 20px}th,td{padding:3px 10px;border-bottom:1px solid #ddd;text-align:left}"
                  "th{font-weight:600;color:#444}.chart{display:block;margin:8px 0 18px;background:#fcfcfc;border:1px solid #eee}"
                  ".title{font-weight:600;font-size:13px}.tick{font-size:11px;fill:#555}.grid{stroke:#e5e5e5}"
                  ".mark{stroke:#d33;stroke-dasharray:3,3}</style></head><body>\n";
  h += fmt::format("<h1>vtsim replay: {} ({} clock)</h1>\n", escape(s.value("system", "")), escape(s.value("clock", "")));
  h += fmt::format("<p>trace <code>{}</code>: {} frames, {:.1f} s at {:.4g} Hz. Metrics are defined in docs/metrics.md.</p>\n",
                   escape(s["trace"].value("name", "")), s["trace"].value("frames", 0), num(s, "trace", "duration_s"), fps);
  h += "<table>\n";
  h += row("disk read", fmt::format("{:.3f} MB/s ({:.0f} bytes)", num(s, "bandwidth", "disk_read_MBps"), num(s, "bandwidth", "disk_read_bytes")));
  h += row("decoded / uploaded", fmt::format("{:.3f} / {:.3f} MB/s", num(s, "bandwidth", "decoded_MBps"), num(s, "bandwidth", "upload_MBps")));
  h += row("upload per frame", fmt::format("p50 {:.0f} B, p99 {:.0f} B, max {:.0f} B", num(s, "bandwidth", "upload_bytes_per_frame", "p50"),
                                           num(s, "bandwidth", "upload_bytes_per_frame", "p99"), num(s, "bandwidth", "upload_bytes_per_frame", "max")));
  h += row("latency", fmt::format("p50 {:.1f} ms, p95 {:.1f} ms, p99 {:.1f} ms, max {:.1f} ms ({:.0f} tiles)", num(s, "latency_ms", "p50"),
                                  num(s, "latency_ms", "p95"), num(s, "latency_ms", "p99"), num(s, "latency_ms", "max"), num(s, "latency_ms", "tiles")));
  h += row("pop-in", fmt::format("blurry {:.2f}% mean, {:.2f}% p99; mean deficit {:.3f} levels; {:.0f} visible pops",
                                 100 * num(s, "popin", "blurry_fraction_mean"), 100 * num(s, "popin", "blurry_fraction_p99"),
                                 num(s, "popin", "mean_deficit"), num(s, "popin", "visible_pops")));
  h += row("time to sharp", fmt::format("{:.2f} s mean, {:.2f} s max over {:.0f} cuts/turns", num(s, "popin", "time_to_sharp_s", "mean"),
                                        num(s, "popin", "time_to_sharp_s", "max"), num(s, "popin", "time_to_sharp_s", "events")));
  h += row("cache", fmt::format("RAM hit ratio {:.1f}%, {:.0f} RAM evictions, {:.0f} VRAM evictions", 100 * num(s, "cache", "ram_hit_ratio"),
                                num(s, "cache", "ram_evictions"), num(s, "cache", "vram_evictions")));
  h += row("throttle", fmt::format("{:.0f} frames throttled, max clamp {:.0f}, {:.0f} changes", num(s, "throttle", "frames_throttled"),
                                   num(s, "throttle", "max_clamp"), num(s, "throttle", "changes")));
  h += row("run", fmt::format("{:.2f} s wall, {:.0f}× real time", num(s, "run", "wall_s"), num(s, "run", "x_realtime")));
  h += "</table>\n";
  h += chart("Blurry fraction (samples drawn ≥ 1 level coarser than wanted); dashed: cuts and fast turns", "%", t,
             {{"blurry", "#c0392b", blurry}}, events);
  h += chart("MaxTextureLOD clamp and the finest level any sample wants", "level", t,
             {{"clamp", "#8e44ad", clamp}, {"finest wanted", "#16a085", finest}}, events, true);
  h += chart("Disk read and upload, 0.25 s moving average", "MB/s", t,
             {{"disk read", "#2c3e50", disk}, {"upload", "#e67e22", upload}}, events);
  h += chart("Requests in the pipeline (queued, in flight, waiting for upload)", "tiles", t, {{"live", "#2980b9", live}}, events);
  if (!lat.empty()) {
    std::vector<double> x, y;
    for (std::size_t i = 0; i < lat.size(); ++i) {
      x.push_back(lat[i] / 1e3);
      y.push_back(100.0 * static_cast<double>(i + 1) / static_cast<double>(lat.size()));
    }
    h += chart("Latency: share of tiles resident within x (x axis in seconds)", "% of tiles", x, {{"tiles", "#27ae60", y}}, {}, true);
  }
  // metrics.opt: each level's LRU miss-ratio curve from the summary with its knee, and above it the
  // offline figures at the run's capacity and the live miss ratio.
  const auto mrc_section = [&](const nlohmann::json& b, const char* title, double live_ratio) {
    const auto& mj = b["mrc"];
    MissRatioCurve c;
    c.unit = mj["unit"] == "bytes" ? MrcUnit::kBytes : MrcUnit::kPages;
    c.capacity = mj["capacity"].get<std::vector<std::uint64_t>>();
    c.miss_ratio = mj["miss_ratio"].get<std::vector<double>>();
    if (mj["knee"].is_object()) {  // the knee the run found on its fine grid (mrc.h), not one on these points
      c.knee.found = true;
      c.knee.capacity = mj["knee"]["capacity"].get<std::uint64_t>();
      c.knee.miss_ratio = mj["knee"]["miss_ratio"].get<double>();
      c.knee.index = static_cast<std::size_t>(std::lower_bound(c.capacity.begin(), c.capacity.end(), c.knee.capacity) -
                                              c.capacity.begin());
      if (c.knee.index >= c.capacity.size()) c.knee.index = c.capacity.size() - 1;
    }
    h += "<h2>" + escape(title) + "</h2>\n";
    h += "<p>Offline at the run's capacity (" + std::to_string(b["capacity"].get<std::uint64_t>()) + " " +
         mrc_unit_name(c.unit) + (c.unit == MrcUnit::kPages ? " free for unlocked pages; the curve's sizes count every slot" : "") +
         "): " + escape(b["policy"].get<std::string>()) + " " +
         std::to_string(b["policy_offline_misses"].get<std::uint64_t>()) + " misses, LRU " +
         std::to_string(b["lru_offline_misses"].get<std::uint64_t>()) + ", Belady " +
         (b.contains("opt_misses") ? std::to_string(b["opt_misses"].get<std::uint64_t>())
                                   : std::to_string(b["opt_misses_lower"].get<std::uint64_t>()) + " to " +
                                         std::to_string(b["opt_misses_upper"].get<std::uint64_t>())) +
         fmt::format("; live miss ratio {:.4f}", live_ratio) + " (docs/cache.md).</p>\n";
    h += mrc_chart_svg({{"LRU", c}}, title);
  };
  const nlohmann::json* cache = s.contains("cache") ? &s["cache"] : nullptr;
  if (cache && cache->contains("ram_bounds")) {
    const double acc = num(s, "cache", "ram_hits") + num(s, "cache", "ram_misses");
    mrc_section((*cache)["ram_bounds"], "RAM: LRU miss-ratio curve of the recorded accesses",
                acc > 0 ? num(s, "cache", "ram_misses") / acc : 0.0);
  }
  if (s.contains("vt") && s["vt"].contains("pool") && s["vt"]["pool"].contains("bounds")) {
    const auto& pool = s["vt"]["pool"];
    const double acc = pool["hits"].get<double>() + pool["misses"].get<double>();
    mrc_section(pool["bounds"], "VT page pool: LRU miss-ratio curve of the recorded accesses",
                acc > 0 ? pool["misses"].get<double>() / acc : 0.0);
  }
  h += html_run_identity(s);
  h += "</body></html>\n";
  return h;
}

}  // namespace vtsim
