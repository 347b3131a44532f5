#include "sim/report/report_runs.h"

#include "sim/run/metric_direction.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <string_view>
#include <utility>

#include "core/error.h"
#include "core/text.h"
#include "sim/report/html_escape.h"
#include "sim/report/report_html.h"
#include "sim/report/svg_chart.h"

namespace vtsim {

namespace {

void rr_flatten(const nlohmann::json& j, const std::string& path, std::size_t max_array,
                std::vector<std::pair<std::string, nlohmann::json>>& out) {
  const auto join = [&](const std::string& k) { return path.empty() ? k : path + "." + k; };
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) rr_flatten(it.value(), join(it.key()), max_array, out);
  } else if (j.is_array()) {
    if (j.size() > max_array) return;
    for (std::size_t i = 0; i < j.size(); ++i) {
      const nlohmann::json& e = j[i];
      const bool by_level = e.is_object() && e.contains("level") && e["level"].is_number_integer();
      rr_flatten(e, join(by_level ? "level" + std::to_string(e["level"].get<long long>()) : std::to_string(i)), max_array, out);
    }
  } else {
    out.emplace_back(path, j);
  }
}

double rr_num(const nlohmann::json& j, std::initializer_list<const char*> keys) {
  const nlohmann::json* p = &j;
  for (const char* k : keys) {
    if (!p->is_object() || !p->contains(k)) return std::nan("");
    p = &(*p)[k];
  }
  return p->is_number() ? p->get<double>() : std::nan("");
}

std::string rr_cell(const nlohmann::json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_float()) return fmt::format("{:.6g}", v.get<double>());
  return v.dump();
}

std::vector<std::string_view> rr_split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= line.size(); ++i)
    if (i == line.size() || line[i] == ',') {
      out.push_back(line.substr(start, i - start));
      start = i + 1;
    }
  return out;
}

// A series sampled at times `at`: the value of the last frame at or before each time (the first
// frame's before it starts); empty when the run has no frames.
std::vector<double> rr_resample(const std::vector<double>& t, const std::vector<double>& v, const std::vector<double>& at) {
  std::vector<double> out;
  if (t.empty()) return out;
  for (double x : at) {
    const auto it = std::upper_bound(t.begin(), t.end(), x + 1e-9);
    out.push_back(v[it == t.begin() ? 0 : static_cast<std::size_t>(it - t.begin()) - 1]);
  }
  return out;
}

// Bytes per frame as MB/s, 0.25 s moving average (as the replay report).
std::vector<double> rr_rate(const std::vector<double>& t, const std::vector<double>& bytes) {
  std::vector<double> out;
  double sum = 0;
  std::size_t first = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    sum += bytes[i];
    while (first < i && t[i] - t[first] >= 0.25 - 1e-9) sum -= bytes[first++];
    const double span = i > first ? t[i] - t[first] + (t[i] - t[i - 1]) : (i > 0 ? t[i] - t[i - 1] : 0.0);
    out.push_back(span > 0 ? sum / span / 1e6 : 0.0);
  }
  return out;
}

}  // namespace

RunFrames read_run_frames(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open the frames CSV");
  std::string line;
  if (!std::getline(in, line)) throw InputError(path, "empty: expected the header of `vtsim replay --frames`");
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const std::vector<std::string_view> head = rr_split(line);
  const char* const wanted[5] = {"t_s", "disk_bytes", "upload_bytes", "blurry_fraction", "ram_bytes"};
  std::size_t col[5];
  for (int k = 0; k < 5; ++k) {
    const auto it = std::find(head.begin(), head.end(), std::string_view(wanted[k]));
    if (it == head.end()) throw InputError(path, std::string("no column '") + wanted[k] + "' (write it with vtsim replay --frames)");
    col[k] = static_cast<std::size_t>(it - head.begin());
  }
  RunFrames f;
  std::vector<double>* dest[5] = {&f.t_s, &f.disk_bytes, &f.upload_bytes, &f.blurry, &f.ram_bytes};
  long long n = 1;
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::vector<std::string_view> cells = rr_split(line);
    for (int k = 0; k < 5; ++k) {
      if (col[k] >= cells.size()) throw InputError(at_line(path, n), std::string("no value in column '") + wanted[k] + "'");
      double v = 0;
      const std::string_view c = cells[col[k]];
      if (!text::parse_whole(c, v) || !std::isfinite(v))
        throw InputError(at_line(path, n), std::string("column '") + wanted[k] + "': '" + std::string(c.substr(0, 40)) + "' is not a number");
      dest[k]->push_back(v);
    }
    if (f.t_s.size() > 1 && f.t_s.back() < f.t_s[f.t_s.size() - 2])
      throw InputError(at_line(path, n), "column 't_s': time goes backwards");
  }
  return f;
}

std::vector<std::pair<std::string, nlohmann::json>> flatten_scalars(const nlohmann::json& j, std::size_t max_array) {
  std::vector<std::pair<std::string, nlohmann::json>> out;
  rr_flatten(j, "", max_array, out);
  return out;
}

std::string html_runs_report(const std::vector<ReportRun>& runs) {
  std::string h = report_page_head("vtsim report: " + std::to_string(runs.size()) + " runs");
  h += fmt::format("<h1>vtsim report: {} runs side by side</h1>\n", runs.size());
  h += "<p>Metrics are defined in docs/metrics.md; this page in docs/report.md. Colours follow the runs in this order.</p>\n";
  h += "<table><tr><th>run</th><th>system</th><th>clock</th><th>trace</th><th>frames</th><th>duration</th><th>vtsim</th></tr>\n";
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const nlohmann::json& s = runs[i].summary;
    const nlohmann::json tr = s.contains("trace") && s["trace"].is_object() ? s["trace"] : nlohmann::json::object();
    h += fmt::format("<tr><td><span style=\"color:{}\">■</span> {}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"num\">{}</td>"
                     "<td class=\"num\">{:.1f} s</td><td>{}</td></tr>\n",
                     chart_colour(i), html_escape(runs[i].name), html_escape(s.value("system", "?")), html_escape(s.value("clock", "?")),
                     html_escape(tr.value("name", "?")), tr.value("frames", 0), rr_num(s, {"trace", "duration_s"}),
                     html_escape(summary_version(s)));
  }
  h += "</table>\n<div class=\"charts\">\n";
  std::vector<std::string> names;
  for (const ReportRun& r : runs) names.push_back(r.name);
  const auto per_run = [&](const std::string& label, const char* colour, std::initializer_list<const char*> path, double scale = 1.0) {
    BarSeries b{label, colour, {}};
    for (const ReportRun& r : runs) b.v.push_back(scale * rr_num(r.summary, path));
    return b;
  };
  h += bar_chart_svg("Latency", "ms from first needed to resident", names,
                     {per_run("p50", chart_colour(0), {"latency_ms", "p50"}), per_run("p95", chart_colour(3), {"latency_ms", "p95"}),
                      per_run("p99", chart_colour(1), {"latency_ms", "p99"})});
  h += bar_chart_svg("Pop-in", "% of samples drawn ≥ 1 level coarser than wanted", names,
                     {per_run("mean", chart_colour(0), {"popin", "blurry_fraction_mean"}, 100),
                      per_run("p99", chart_colour(1), {"popin", "blurry_fraction_p99"}, 100)});
  h += bar_chart_svg("Bandwidth", "MB/s averaged over the run", names,
                     {per_run("disk read", chart_colour(0), {"bandwidth", "disk_read_MBps"}),
                      per_run("upload", chart_colour(3), {"bandwidth", "upload_MBps"})});
  h += bar_chart_svg("Upload per frame", "bytes uploaded in one frame", names,
                     {per_run("p50", chart_colour(0), {"bandwidth", "upload_bytes_per_frame", "p50"}),
                      per_run("p99", chart_colour(1), {"bandwidth", "upload_bytes_per_frame", "p99"})});
  {
    std::vector<std::string> stages;
    for (const char* k : {"queue", "io", "decode_wait", "decode", "upload_wait", "upload"}) stages.push_back(k);
    std::vector<BarSeries> series;
    for (std::size_t i = 0; i < runs.size(); ++i) {
      BarSeries b{runs[i].name, chart_colour(i), {}};
      for (const std::string& st : stages) b.v.push_back(rr_num(runs[i].summary, {"latency_ms", "stages_ms", st.c_str(), "p95"}));
      series.push_back(std::move(b));
    }
    h += bar_chart_svg("Latency by stage, p95", "ms per tile in each stage (docs/pipeline.md)", stages, series);
  }
  {
    std::set<long long> levels;
    for (const ReportRun& r : runs)
      if (r.summary.contains("bandwidth") && r.summary["bandwidth"].contains("per_level") && r.summary["bandwidth"]["per_level"].is_array())
        for (const auto& l : r.summary["bandwidth"]["per_level"])
          if (l.is_object() && l.contains("level") && l["level"].is_number_integer()) levels.insert(l["level"].get<long long>());
    if (!levels.empty()) {
      std::vector<std::string> groups;
      for (long long l : levels) groups.push_back("level " + std::to_string(l));
      std::vector<BarSeries> series;
      for (std::size_t i = 0; i < runs.size(); ++i) {
        BarSeries b{runs[i].name, chart_colour(i), std::vector<double>(levels.size(), 0.0)};
        const nlohmann::json& s = runs[i].summary;
        if (s.contains("bandwidth") && s["bandwidth"].contains("per_level") && s["bandwidth"]["per_level"].is_array())
          for (const auto& l : s["bandwidth"]["per_level"])
            if (l.is_object() && l.contains("level") && l["level"].is_number_integer())
              b.v[static_cast<std::size_t>(std::distance(levels.begin(), levels.find(l["level"].get<long long>())))] =
                  rr_num(l, {"disk_read_MBps"});
        series.push_back(std::move(b));
      }
      h += bar_chart_svg("Disk read per level", "MB/s averaged over the run, by mip level (0 = finest)", groups, series);
    }
  }
  h += "</div>\n";
  // Over time, when frames CSVs were given: every run on the time axis of the first run with frames.
  const auto with_frames = std::find_if(runs.begin(), runs.end(), [](const ReportRun& r) { return !r.frames.t_s.empty(); });
  if (with_frames != runs.end()) {
    const std::vector<double>& at = with_frames->frames.t_s;
    TimeChart disk{"Disk read", "0.25 s moving average, per run", "MB/s", "s", at, {}, {}, ""};
    TimeChart blur{"Blurry fraction", "samples drawn ≥ 1 level coarser than wanted, per run", "%", "s", at, {}, {}, "", false};
    TimeChart ram{"RAM cache occupancy", "decoded tiles held in RAM, per run", "MiB", "s", at, {}, {}, "", false};
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const RunFrames& f = runs[i].frames;
      if (f.t_s.empty()) continue;
      std::vector<double> pc, mib;
      for (double v : f.blurry) pc.push_back(100 * v);
      for (double v : f.ram_bytes) mib.push_back(v / (1024.0 * 1024.0));
      disk.lines.push_back({runs[i].name, chart_colour(i), rr_resample(f.t_s, rr_rate(f.t_s, f.disk_bytes), at)});
      blur.lines.push_back({runs[i].name, chart_colour(i), rr_resample(f.t_s, pc, at)});
      ram.lines.push_back({runs[i].name, chart_colour(i), rr_resample(f.t_s, mib, at), true});
    }
    h += "<h2>Over time</h2>\n<div class=\"charts\">\n" + time_chart_svg(disk) + time_chart_svg(blur) + time_chart_svg(ram) + "</div>\n";
  }
  // Every scalar, rows in first-seen order; the config rows (summary "config") first.
  std::vector<std::string> order;
  std::map<std::string, std::vector<const nlohmann::json*>> cells;
  std::vector<std::vector<std::pair<std::string, nlohmann::json>>> flat;
  for (const ReportRun& r : runs) flat.push_back(flatten_scalars(r.summary));
  for (std::size_t i = 0; i < runs.size(); ++i)
    for (const auto& [k, v] : flat[i]) {
      auto [it, fresh] = cells.try_emplace(k, std::vector<const nlohmann::json*>(runs.size(), nullptr));
      if (fresh) order.push_back(k);
      it->second[i] = &v;
    }
  std::stable_partition(order.begin(), order.end(), [](const std::string& k) { return k.rfind("config.", 0) == 0; });
  std::size_t differing = 0;
  std::string rows;
  std::vector<double> served;  // each run's served fraction (1 when it has none)
  for (const ReportRun& r : runs) {
    const nlohmann::json* f = r.summary.is_object() && r.summary.contains("latency_ms") && r.summary["latency_ms"].is_object() &&
                                      r.summary["latency_ms"].contains("served_fraction")
                                  ? &r.summary["latency_ms"]["served_fraction"]
                                  : nullptr;
    served.push_back(f && f->is_number() ? f->get<double>() : 1.0);
  }
  for (const std::string& k : order) {
    const auto& c = cells[k];
    bool differs = false;
    for (const auto* v : c) differs |= !v || !c[0] || *v != *c[0];
    differing += differs;
    const MetricDirection dir = metric_direction(k);
    rows += fmt::format("<tr{}><th>{}</th>", differs ? " class=\"diff\"" : "", html_escape(k));
    for (std::size_t i = 0; i < c.size(); ++i) {
      if (!c[i]) {
        rows += "<td class=\"d\">–</td>";
        continue;
      }
      std::string text = rr_cell(*c[i]);
      if (i > 0 && c[0] && c[i]->is_number() && c[0]->is_number() && *c[i] != *c[0]) {
        const double a = c[0]->get<double>(), b = c[i]->get<double>();
        text += a != 0 ? fmt::format(" ({:+.1f} %)", 100 * (b - a) / std::fabs(a)) : " (was 0)";
      }
      const bool d = i > 0 && (!c[0] || *c[i] != *c[0]);
      // Better or worse than the first run by the metric's direction (docs/metrics.md, "Directions");
      // a lower latency over a smaller served fraction is neither (as vtsim compare judges it).
      std::string judged;
      if (d && c[0] && c[i]->is_number() && c[0]->is_number() && dir != MetricDirection::neither) {
        const bool lower = c[i]->get<double>() < c[0]->get<double>();
        const bool good = dir == MetricDirection::lower ? lower : !lower;
        if (!(good && is_served_latency_key(k) && served[i] < served[0])) judged = good ? " better" : " worse";
      }
      rows += fmt::format("<td class=\"{}{}{}\">{}</td>", c[i]->is_number() ? "num" : "", d ? " d" : "", judged, html_escape(text));
    }
    rows += "</tr>\n";
  }
  h += fmt::format("<h2>Every metric</h2>\n<p>{} values, {} of which differ between the runs (highlighted; changes in % of the first "
                   "run). Config keys come first when the summaries hold their config.</p>\n<table><tr><th>key</th>",
                   order.size(), differing);
  for (const ReportRun& r : runs) h += "<th>" + html_escape(r.name) + "</th>";
  h += "</tr>\n" + rows + "</table>\n</body></html>\n";
  return h;
}

}  // namespace vtsim
