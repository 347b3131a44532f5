#include "sim/report/report_html.h"
#include "sim/report/report_identity.h"

#include "cache/policy/mrc.h"
#include "sim/report/html_escape.h"
#include "sim/report/mrc_chart.h"
#include "sim/report/svg_chart.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

namespace vtsim {

namespace {

std::string escape(const std::string& s) { return html_escape(s); }

std::string row(const std::string& k, const std::string& v) {
  return fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", escape(k), escape(v));
}

double num(const nlohmann::json& j, const char* a, const char* b = nullptr, const char* c = nullptr) {
  const nlohmann::json* p = &j;
  for (const char* k : {a, b, c}) {
    if (!k) break;
    if (!p->is_object() || !p->contains(k)) return 0.0;
    p = &(*p)[k];
  }
  return p->is_number() ? p->get<double>() : 0.0;
}

// A config value as a number (TOML text such as "16", "-1", "256.0"); NaN when absent or not one.
double rh_config_number(const ReportConfig& cfg, std::string_view key) {
  for (const auto& [k, v] : cfg)
    if (k == key) {
      char* end = nullptr;
      const double d = std::strtod(v.c_str(), &end);
      return end != v.c_str() && *end == '\0' ? d : std::nan("");
    }
  return std::nan("");
}

}  // namespace

std::string summary_version(const nlohmann::json& s) {
  const auto text = [](const nlohmann::json& o, const char* key) {
    const auto it = o.find(key);
    return it != o.end() && it->is_string() ? it->get_ref<const std::string&>() : std::string("?");
  };
  const auto p = s.find("provenance");
  if (p != s.end() && p->is_object()) {
    std::string v = text(*p, "vtsim_version");
    v.append(" (commit ").append(text(*p, "vtsim_commit")).append(")");
    return v;
  }
  return text(s, "vtsim_version");
}

namespace {

std::string rh_config_value(const ReportConfig& cfg, std::string_view key) {
  for (const auto& [k, v] : cfg)
    if (k == key) return v;
  return {};
}

void rh_flatten(const nlohmann::json& j, const std::string& prefix, ReportConfig& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) rh_flatten(it.value(), prefix.empty() ? it.key() : prefix + "." + it.key(), out);
    return;
  }
  out.emplace_back(prefix, j.dump());
}

}  // namespace

ReportConfig report_config_of(const nlohmann::json& summary) {
  ReportConfig out;
  if (summary.is_object() && summary.contains("config") && summary["config"].is_object()) rh_flatten(summary["config"], "", out);
  return out;
}

std::string report_check_script() {
  return R"JS(<script>
(function () {
  if (!/[?&]check\b/.test(location.search)) return;
  var errors = [];
  var oe = console.error;
  console.error = function () { errors.push('console.error: ' + Array.prototype.join.call(arguments, ' ')); oe.apply(console, arguments); };
  window.addEventListener('error', function (e) { errors.push('error: ' + (e.message || e.type)); }, true);
  window.addEventListener('load', function () {
    var problems = [], ntext = 0;
    var svgs = document.querySelectorAll('svg.chart');
    svgs.forEach(function (svg) {
      var sb = svg.getBoundingClientRect(), name = svg.getAttribute('aria-label') || 'chart';
      var ts = Array.prototype.slice.call(svg.querySelectorAll('text'));
      var bs = ts.map(function (t) { return t.getBoundingClientRect(); });
      ntext += ts.length;
      for (var i = 0; i < ts.length; i++) {
        var a = bs[i];
        if (a.width === 0) continue;
        if (a.left < sb.left - 0.5 || a.right > sb.right + 0.5 || a.top < sb.top - 0.5 || a.bottom > sb.bottom + 0.5)
          problems.push(name + ': "' + ts[i].textContent + '" outside its chart');
        for (var j = i + 1; j < ts.length; j++) {
          var b = bs[j];
          var ox = Math.min(a.right, b.right) - Math.max(a.left, b.left), oy = Math.min(a.bottom, b.bottom) - Math.max(a.top, b.top);
          if (ox > 1 && oy > 1) problems.push(name + ': "' + ts[i].textContent + '" overlaps "' + ts[j].textContent + '"');
        }
      }
    });
    var out = document.createElement('pre');
    out.id = 'vtsim-check';
    out.textContent = 'VTSIM-CHECK charts=' + svgs.length + ' texts=' + ntext + ' overlaps=' + problems.length +
                      ' console_errors=' + errors.length + '\n' + problems.concat(errors).join('\n');
    document.body.appendChild(out);
  });
})();
</script>
)JS";
}

std::string report_page_head(const std::string& title) {
  return "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>" + escape(title) + "</title>\n" + report_check_script() +
         "<style>"
         "body{font:14px 'DejaVu Sans',system-ui,sans-serif;margin:20px;color:#222}"
         "h1{font-size:20px;margin:0 0 6px}h2{font-size:16px;margin:22px 0 6px}"
         "table{border-collapse:collapse;margin:6px 0 14px}th,td{padding:2px 10px;border-bottom:1px solid #ddd;text-align:left;"
         "vertical-align:top}th{font-weight:600;color:#444}td.num{text-align:right;font-variant-numeric:tabular-nums}"
         ".top{display:flex;flex-wrap:wrap;gap:10px 32px;align-items:flex-start}"
         ".charts{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start}"
         ".chart{display:block;background:#fcfcfc;border:1px solid #e4e4e4}"
         ".chart text{font-family:'DejaVu Sans',sans-serif}"
         ".title{font-weight:600;font-size:13px}.sub,.lgd,.tick,.val{font-size:11px}.sub{fill:#555}.tick,.val{fill:#444}.lgd{fill:#333}"
         ".grid{stroke:#e5e5e5}.frame{fill:none;stroke:#ccc}.mark{stroke:#d33;stroke-dasharray:3,3}"
         ".cfg{columns:2 420px;font:12px 'DejaVu Sans Mono',monospace}.cfg div{break-inside:avoid}"
         "tr.diff td.d{background:#fff3cd}td.worse{color:#b00}td.better{color:#070}"
         "</style></head><body>\n";
}

namespace {

// The page's heading and its table of key figures.
std::string rh_key_figures(const nlohmann::json& s, const ReportConfig& config, double fps) {
  const std::string system = s.value("system", "");
  std::string h = report_page_head("vtsim replay report");
  h += fmt::format("<h1>vtsim replay: {} ({} clock)</h1>\n", escape(system), escape(s.value("clock", "")));
  const nlohmann::json trace = s.contains("trace") && s["trace"].is_object() ? s["trace"] : nlohmann::json::object();
  h += fmt::format("<p>trace <code>{}</code>: {} frames, {:.1f} s at {:.4g} Hz; vtsim {}. Metrics are defined in docs/metrics.md, "
                   "the charts in docs/report.md.</p>\n",
                   escape(trace.value("name", "")), trace.value("frames", 0), num(s, "trace", "duration_s"), fps,
                   escape(summary_version(s)));
  h += "<div class=\"top\"><table>\n";
  h += row("disk read", fmt::format("{:.3f} MB/s ({:.0f} bytes)", num(s, "bandwidth", "disk_read_MBps"), num(s, "bandwidth", "disk_read_bytes")));
  h += row("decoded / uploaded", fmt::format("{:.3f} / {:.3f} MB/s", num(s, "bandwidth", "decoded_MBps"), num(s, "bandwidth", "upload_MBps")));
  h += row("upload per frame", fmt::format("p50 {:.0f} B, p99 {:.0f} B, max {:.0f} B", num(s, "bandwidth", "upload_bytes_per_frame", "p50"),
                                           num(s, "bandwidth", "upload_bytes_per_frame", "p99"), num(s, "bandwidth", "upload_bytes_per_frame", "max")));
  h += row("latency", fmt::format("p50 {:.1f} ms, p95 {:.1f} ms, p99 {:.1f} ms, max {:.1f} ms ({:.0f} tiles)", num(s, "latency_ms", "p50"),
                                  num(s, "latency_ms", "p95"), num(s, "latency_ms", "p99"), num(s, "latency_ms", "max"), num(s, "latency_ms", "count")));
  if (s.contains("latency_ms") && s["latency_ms"].is_object() && s["latency_ms"].value("served_fraction", nlohmann::json()).is_number())
    h += row("served", fmt::format("{:.1f}% of {:.0f} requests; {:.0f} never served (waited p95 {:.1f} ms)",
                                   100 * num(s, "latency_ms", "served_fraction"), num(s, "latency_ms", "requests"),
                                   num(s, "latency_ms", "censored", "count"), num(s["latency_ms"], "censored", "wait_ms", "p95")));
  h += row("pop-in", fmt::format("blurry {:.2f}% mean, {:.2f}% p99; mean deficit {:.3f} levels; {:.0f} visible pops",
                                 100 * num(s, "popin", "blurry_fraction_mean"), 100 * num(s, "popin", "blurry_fraction_p99"),
                                 num(s, "popin", "mean_deficit"), num(s, "popin", "visible_pops")));
  const bool has_tts = s.contains("popin") && s["popin"].is_object() && s["popin"].contains("time_to_sharp_s") &&
                       s["popin"]["time_to_sharp_s"].is_object() && s["popin"]["time_to_sharp_s"].value("mean", nlohmann::json()).is_number();
  h += row("time to sharp", has_tts ? fmt::format("{:.2f} s mean, {:.2f} s max over {:.0f} cuts/turns", num(s, "popin", "time_to_sharp_s", "mean"),
                                                  num(s, "popin", "time_to_sharp_s", "max"), num(s, "popin", "time_to_sharp_s", "events"))
                                    : fmt::format("none: {:.0f} cuts/turns, none became sharp", num(s, "popin", "time_to_sharp_s", "events")));
  h += row("cache", fmt::format("RAM hit ratio {:.1f}%, {:.0f} RAM evictions, {:.0f} VRAM evictions", 100 * num(s, "cache", "ram_hit_ratio"),
                                num(s, "cache", "ram_evictions"), num(s, "cache", "vram_evictions")));
  h += row("throttle", fmt::format("{:.0f} frames throttled, max clamp {:.0f}, {:.0f} changes", num(s, "throttle", "frames_throttled"),
                                   num(s, "throttle", "max_clamp"), num(s, "throttle", "changes")));
  if (!config.empty()) {
    const std::string disk_preset = rh_config_value(config, "disk.preset");
    const std::string byte_budget = rh_config_value(config, "upload.bytes_per_frame");
    h += row("storage", fmt::format("disk {}, RAM {} MiB, upload {} tiles per frame, {}", disk_preset.empty() ? "?" : disk_preset,
                                    rh_config_value(config, "ram.capacity_MiB"), rh_config_value(config, "upload.tiles_per_frame"),
                                    byte_budget == "-1" || byte_budget.empty() ? "no byte limit" : byte_budget + " bytes per frame"));
  }
  h += row("run", fmt::format("{:.2f} s wall, {:.0f}× real time", num(s, "run", "wall_s"), num(s, "run", "x_realtime")));
  h += "</table></div>\n";
  return h;
}

// The charts over time: the frames' series (disk and upload as 0.25 s moving averages), with cuts
// and fast turns marked; the VT pool's when the system has one.
std::string rh_over_time(const MetricsCollector& m, const ReportConfig& config, double fps) {
  const auto& frames = m.frames();
  std::vector<double> t, blurry, clamp, finest, disk, upload, live, needs, ram, up_tiles, up_bytes;
  std::vector<double> events;
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
    needs.push_back(r.needs);
    ram.push_back(static_cast<double>(r.ram_bytes) / (1024.0 * 1024.0));
    up_tiles.push_back(r.uploads);
    up_bytes.push_back(static_cast<double>(r.upload_bytes) / 1024.0);
    if (r.event) events.push_back(r.t_s);
  }
  // A system column by name (FrameRow::system), empty when the system has none.
  const auto column = [&](std::string_view name) {
    std::vector<double> v;
    const auto& names = m.system_columns();
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) return v;
    const auto k = static_cast<std::size_t>(it - names.begin());
    for (const FrameRow& r : frames) v.push_back(r.system[k]);
    return v;
  };
  std::string h;
  h += "<h2>Over time</h2>\n<div class=\"charts\">\n";
  const std::string cuts = "cut / fast turn";
  // A share: its full range, never clipped (a clipped 100 % would read as an error).
  h += time_chart_svg({"Blurry fraction", "samples drawn ≥ 1 level coarser than wanted", "%", "s", t, {{"blurry", chart_colour(1), blurry}},
                       events, cuts, false});
  h += time_chart_svg({"MaxTextureLOD clamp and the finest level wanted", "level (0 = finest)", "", "s", t,
                       {{"clamp", chart_colour(4), clamp, true}, {"finest wanted", chart_colour(2), finest, true}}, events, cuts, false});
  h += time_chart_svg({"Disk read and upload", "0.25 s moving average", "MB/s", "s", t,
                       {{"disk read", chart_colour(0), disk}, {"upload", chart_colour(3), upload}}, events, cuts});
  {
    TimeChart c{"Upload per frame against the budget", "tiles uploaded each frame", "tiles", "s", t, {{"uploaded", chart_colour(3), up_tiles, true}},
                {}, ""};
    const double budget = rh_config_number(config, "upload.tiles_per_frame");
    if (budget > 0) c.lines.push_back({"budget (upload.tiles_per_frame)", "#555", std::vector<double>(t.size(), budget), false, true});
    h += time_chart_svg(c);
    const double byte_budget = rh_config_number(config, "upload.bytes_per_frame");
    if (byte_budget > 0) {
      TimeChart b{"Upload bytes per frame against the budget", "KiB uploaded each frame", "KiB", "s", t,
                  {{"uploaded", chart_colour(3), up_bytes, true},
                   {"budget (upload.bytes_per_frame)", "#555", std::vector<double>(t.size(), byte_budget / 1024.0), false, true}},
                  {}, ""};
      h += time_chart_svg(b);
    }
  }
  h += time_chart_svg({"Requests in the pipeline", "queued, in flight, waiting for upload; and tiles needed, not resident", "tiles", "s", t,
                       {{"in the pipeline", chart_colour(0), live}, {"needed, not resident", chart_colour(5), needs}}, events, cuts});
  {
    TimeChart c{"RAM cache occupancy", "decoded tiles held in RAM", "MiB", "s", t, {{"RAM", chart_colour(0), ram, true}}, {}, "", false};
    const double cap = rh_config_number(config, "ram.capacity_MiB");
    if (cap > 0) c.lines.push_back({"capacity (ram.capacity_MiB)", "#555", std::vector<double>(t.size(), cap), false, true});
    h += time_chart_svg(c);
  }
  if (const auto occ = column("vt_pool_occupancy"); !occ.empty()) {
    const auto pressure = column("vt_pool_pressure");
    std::vector<double> occ_pc, pressure_pc;
    for (double v : occ) occ_pc.push_back(100 * v);
    for (double v : pressure) pressure_pc.push_back(100 * v);
    TimeChart c{"VT page pool: occupancy and pressure", "share of the pool's slots: used recently; wanted this frame", "% of slots", "s", t,
                {{"occupancy", chart_colour(0), occ_pc}, {"pressure", chart_colour(1), pressure_pc}}, events, cuts, false};
    c.y_max_hint = 100;
    const double hw = rh_config_number(config, "throttle.high_water");
    if (hw > 0) c.lines.push_back({"high water (throttle.high_water)", "#555", std::vector<double>(t.size(), 100 * hw), false, true});
    h += time_chart_svg(c);
    std::vector<double> bias;
    for (const FrameRow& r : frames) bias.push_back(r.bias);
    h += time_chart_svg({"VT feedback LOD bias", "levels added to every desired level by the residency policy", "levels", "s", t,
                         {{"bias", chart_colour(4), bias, true}}, events, cuts, false});
  }
  return h;
}

// The latency distribution, latency by stage and bandwidth per level.
std::string rh_latency_charts(const nlohmann::json& s, const MetricsCollector& m) {
  std::string h;
  // Latency distribution: the share of tiles resident within x ms (a CDF). The x axis ends at the
  // robust scale of the latencies; a tail beyond it is stated in the subtitle.
  std::vector<double> lat;
  for (const auto& l : m.latencies()) lat.push_back(ticks_to_ms(l.total));
  std::sort(lat.begin(), lat.end());
  if (!lat.empty()) {
    const ChartScale xs = robust_scale(lat);
    std::vector<double> x{0.0}, y{0.0};  // the axis starts at 0 ms
    for (std::size_t i = 0; i < lat.size() && lat[i] <= xs.hi; ++i) {
      x.push_back(lat[i]);
      y.push_back(100.0 * static_cast<double>(i + 1) / static_cast<double>(lat.size()));
    }
    const std::string sub = xs.clipped ? fmt::format("% of tiles resident within x ms; {:.1f} % beyond the axis, max {} ms",
                                                     100.0 - (y.empty() ? 0.0 : y.back()), fmt::format("{:.0f}", xs.max))
                                       : "% of tiles resident within x ms";
    TimeChart c{"Latency: first needed to resident", sub, "", "ms", x, {{"tiles", chart_colour(2), y, true}}, {}, "", false, 100};
    h += time_chart_svg(c);
  }
  if (s.contains("latency_ms") && s["latency_ms"].contains("stages_ms") && s["latency_ms"]["stages_ms"].is_object()) {
    const auto& st = s["latency_ms"]["stages_ms"];
    std::vector<std::string> groups;
    std::vector<BarSeries> series{{"p50", chart_colour(0), {}}, {"p95", chart_colour(3), {}}, {"p99", chart_colour(1), {}}};
    for (const char* k : {"queue", "io", "decode_wait", "decode", "upload_wait", "upload"}) {
      if (!st.contains(k)) continue;
      groups.push_back(k);
      series[0].v.push_back(num(st, k, "p50"));
      series[1].v.push_back(num(st, k, "p95"));
      series[2].v.push_back(num(st, k, "p99"));
    }
    h += bar_chart_svg("Latency by stage", "ms per tile in each stage of the pipeline (docs/pipeline.md)", groups, series);
  }
  if (s.contains("bandwidth") && s["bandwidth"].contains("per_level") && s["bandwidth"]["per_level"].is_array() &&
      !s["bandwidth"]["per_level"].empty()) {
    std::vector<std::string> groups;
    std::vector<BarSeries> series{{"disk read", chart_colour(0), {}}, {"upload", chart_colour(3), {}}};
    for (const auto& l : s["bandwidth"]["per_level"]) {
      groups.push_back(fmt::format("level {}", l.value("level", 0)));
      series[0].v.push_back(num(l, "disk_read_MBps"));
      series[1].v.push_back(num(l, "upload_MBps"));
    }
    h += bar_chart_svg("Bandwidth per level", "MB/s averaged over the run, by mip level (0 = finest)", groups, series);
  }
  return h;
}

// metrics.opt: each level's LRU miss-ratio curve from the summary with its knee, and above it the
// offline figures at the run's capacity and the live miss ratio.
std::string rh_cache_curves(const nlohmann::json& s) {
  std::string h;
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
  return h;
}

}  // namespace

std::string html_report(const nlohmann::json& s, const MetricsCollector& m, const ReportConfig& config_in) {
  const ReportConfig config = config_in.empty() ? report_config_of(s) : config_in;
  const double fps = num(s, "trace", "fps") > 0 ? num(s, "trace", "fps") : 60.0;
  std::string h = rh_key_figures(s, config, fps);
  h += rh_over_time(m, config, fps);
  h += "</div>\n<h2>Latency and bandwidth</h2>\n<div class=\"charts\">\n";
  h += rh_latency_charts(s, m);
  h += "</div>\n";
  h += rh_cache_curves(s);
  if (!config.empty() && !(s.is_object() && s.contains("config"))) {  // else html_run_identity shows it
    h += "<h2>Config</h2>\n<p>Every key of the run's effective config, defaults included (docs/config.md).</p>\n<div class=\"cfg\">\n";
    for (const auto& [k, v] : config) h += "<div>" + escape(k) + " = " + escape(v) + "</div>\n";
    h += "</div>\n";
  }
  h += html_run_identity(s);
  h += "</body></html>\n";
  return h;
}

}  // namespace vtsim
