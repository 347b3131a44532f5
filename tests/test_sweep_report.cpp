// The sweep report (sim/report/sweep_report.h): the Pareto front on hand-made points, and the page
// of synthetic sweeps: every metric chart, the front tables, failed rows escaped, same bytes for
// the same inputs, no axes, one config, a metric the summaries lack.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <set>

#include "sim/report/sweep_report.h"
#include "test_util.h"

using nlohmann::json;
using vtsim::test::contains;

namespace vtsim::sweep_report_test {

using Axes = std::vector<std::pair<std::string, std::vector<std::string>>>;
using SummaryFn = std::function<json(std::size_t config, std::size_t trace, const json& values)>;

const std::vector<std::string> kMetrics = {"popin.blurry_fraction_mean", "popin.time_to_sharp_s.mean", "latency_ms.p99",
                                           "bandwidth.disk_read_MBps", "cache.ram_hit_ratio"};

// A grid sweep's meta and rows as `vtsim sweep` writes them (first axis slowest; costs from
// vt.pool_pages at 64 KiB a page and upload.tiles_per_frame).
std::pair<json, std::vector<json>> grid_sweep(const Axes& axes, std::size_t traces, const SummaryFn& summary,
                                              std::vector<std::string> metrics = kMetrics) {
  std::vector<json> points = {json::object()};
  json meta_axes = json::array(), keys = json::array();
  for (const auto& [key, values] : axes) {
    meta_axes.push_back({{"key", key}, {"values", values}});
    keys.push_back(key);
    std::vector<json> next;
    for (const json& p : points)
      for (const std::string& v : values) {
        json q = p;
        q[key] = v;
        next.push_back(q);
      }
    points = next;
  }
  json configs = json::array(), trace_list = json::array();
  for (std::size_t c = 0; c < points.size(); ++c) {
    const json& v = points[c];
    const double pages = v.contains("vt.pool_pages") ? std::stod(v["vt.pool_pages"].get<std::string>()) : 1024;
    const double tiles = v.contains("upload.tiles_per_frame") ? std::stod(v["upload.tiles_per_frame"].get<std::string>()) : 16;
    configs.push_back({{"config", c},
                       {"values", v},
                       {"cost", {{"pool_MiB", pages / 16}, {"ram_MiB", 256.0}, {"upload_tiles_per_frame", tiles},
                                 {"upload_MiB_per_frame", 0.0}}}});
  }
  for (std::size_t t = 0; t < traces; ++t)
    trace_list.push_back({{"trace", t}, {"name", "walk duration_s=20 #" + std::to_string(t)}, {"source", "traces/t" + std::to_string(t) + ".csv"}});
  // blur_bound 0.5: every config of these grids competes on the fronts (their blur is up to 0.45).
  const json meta = {{"schema", "vtsim.sweep/1"}, {"name", "pool-vs-upload"},  {"spec_hash", "0123abcd"}, {"blur_bound", 0.5},
                     {"axes", meta_axes},         {"axis_keys", keys},         {"metrics", metrics},
                     {"configs", configs},        {"traces", trace_list}};
  std::vector<json> rows;
  for (std::size_t c = 0; c < points.size(); ++c)
    for (std::size_t t = 0; t < traces; ++t)
      rows.push_back({{"row", rows.size()}, {"config", c}, {"trace", t}, {"values", points[c]}, {"status", "ok"},
                      {"summary", summary(c, t, points[c])}});
  return {meta, rows};
}

json popin_summary(double blurry, double scale) {
  return {{"popin", {{"blurry_fraction_mean", blurry * scale}, {"time_to_sharp_s", {{"mean", 2 * blurry * scale}}}}},
          {"latency_ms", {{"p99", 100 * blurry * scale}}},
          {"bandwidth", {{"disk_read_MBps", (1 - blurry) * 10}}},
          {"cache", {{"ram_hit_ratio", 1 - blurry}}}};
}

// The configs listed in the front table of (pop-in metric, cost).
std::set<int> front_configs(const std::string& html, const std::string& popin, const std::string& cost) {
  const std::string open = "<table class=\"front\" data-popin=\"" + popin + "\" data-cost=\"" + cost + "\">";
  const std::size_t at = html.find(open);
  if (at == std::string::npos) return {-1};  // no table
  const std::string table = html.substr(at, html.find("</table>", at) - at);
  std::set<int> configs;
  for (std::size_t p = table.find("data-config=\""); p != std::string::npos; p = table.find("data-config=\"", p + 1))
    configs.insert(std::stoi(table.substr(p + 13)));
  return configs;
}

// The 2×2 grid of the tests: blurry fraction per config 0.30, 0.20, 0.25, 0.10 on trace 0, twice
// that on trace 1; config 1 and 3 are the front against the pool, 2 and 3 against the upload budget.
std::pair<json, std::vector<json>> two_by_two() {
  const double blurry[] = {0.30, 0.20, 0.25, 0.10};
  return grid_sweep({{"vt.pool_pages", {"256", "512"}}, {"upload.tiles_per_frame", {"4", "8"}}}, 2,
                    [&](std::size_t c, std::size_t t, const json&) { return popin_summary(blurry[c], t == 0 ? 1.0 : 2.0); });
}

}  // namespace vtsim::sweep_report_test

using namespace vtsim::sweep_report_test;

TEST_CASE("sweep report: pareto_front keeps the undominated points, sorted by cost") {
  using vtsim::pareto_front;
  using P = std::vector<std::pair<double, double>>;
  // (3,4) is beaten by (2,3); (5,1) by (4,1); index 4 repeats index 1 and goes.
  CHECK(pareto_front(P{{1, 5}, {2, 3}, {3, 4}, {4, 1}, {2, 3}, {5, 1}}) == std::vector<std::size_t>{0, 1, 3});
  CHECK(pareto_front(P{{4, 1}, {1, 5}, {2, 3}}) == std::vector<std::size_t>{1, 2, 0});  // sorted by x, not input order
  CHECK(pareto_front(P{{1, 2}, {1, 1}}) == std::vector<std::size_t>{1});                   // same cost: the lower pop-in
  CHECK(pareto_front(P{{2, 1}, {1, 1}}) == std::vector<std::size_t>{1});                   // same pop-in: the lower cost
  CHECK(pareto_front(P{{7, 7}}) == std::vector<std::size_t>{0});
  CHECK(pareto_front(P{{3, 3}, {3, 3}, {3, 3}}) == std::vector<std::size_t>{0});
  CHECK(pareto_front(P{}).empty());
  const double inf = std::numeric_limits<double>::infinity();  // an unlimited budget costs the most
  CHECK(pareto_front(P{{inf, 0}, {4, 1}, {inf, 0}}) == std::vector<std::size_t>{1, 0});
  CHECK(pareto_front(P{{std::nan(""), 0}, {1, 1}}) == std::vector<std::size_t>{1});
}

TEST_CASE("sweep report: a 2x2 grid over 2 traces has every chart and the expected fronts") {
  const auto [meta, rows] = two_by_two();
  const std::string html = vtsim::sweep_report_html(meta, rows);
  CHECK(contains(html, "pool-vs-upload"));
  CHECK(contains(html, "0123abcd"));
  CHECK(contains(html, "4 configs × 2 traces = 8 rows"));
  CHECK(contains(html, "<b>0 rows</b> failed"));
  for (const std::string& m : kMetrics) {
    CHECK_MESSAGE(contains(html, "aria-label=\"" + m + " over vt.pool_pages\""), m);
    CHECK_MESSAGE(contains(html, "aria-label=\"" + m + " over upload.tiles_per_frame\""), m);
    CHECK_MESSAGE(contains(html, "<table class=\"breakdown\" data-metric=\"" + m + "\">"), m);
  }
  CHECK(front_configs(html, "popin.blurry_fraction_mean", "pool_MiB") == std::set<int>{1, 3});
  CHECK(front_configs(html, "popin.blurry_fraction_mean", "upload_tiles_per_frame") == std::set<int>{2, 3});
  CHECK(front_configs(html, "popin.time_to_sharp_s.mean", "pool_MiB") == std::set<int>{1, 3});
  // Disk MB/s is (1 - blurry) * 10: the lower the pop-in, the more it reads: every config is on the front.
  CHECK(front_configs(html, "popin.blurry_fraction_mean", "disk_MBps") == std::set<int>{0, 1, 2, 3});
  // Constant across configs: no chart.
  CHECK(front_configs(html, "popin.blurry_fraction_mean", "ram_MiB") == std::set<int>{-1});
  CHECK(front_configs(html, "popin.blurry_fraction_mean", "upload_MiB_per_frame") == std::set<int>{-1});
  // Means over the traces: config 3 is 0.10 and 0.20 -> 0.15; lower-is-better colours.
  CHECK(contains(html, "<td class=\"best\" style=\"background:hsl(120,65%,84%)\">0.15</td>"));
  CHECK_FALSE(contains(html, "<script"));
}

TEST_CASE("sweep report: failed rows are listed with their messages escaped") {
  auto [meta, rows] = two_by_two();
  meta["name"] = "<b>bold</b>";
  rows[3] = {{"row", 3}, {"config", 1}, {"trace", 1}, {"values", rows[3]["values"]}, {"status", "error"},
             {"error", "<script>alert('x')</script> & \"more\""}};
  const std::string html = vtsim::sweep_report_html(meta, rows);
  CHECK_FALSE(contains(html, "<script"));
  CHECK_FALSE(contains(html, "<b>bold"));
  CHECK(contains(html, "&lt;b&gt;bold&lt;/b&gt;"));
  CHECK(contains(html, "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;more&quot;"));
  CHECK(contains(html, "<b>1 row</b> failed"));
  // Config 1 lost a trace: its mean is n/a, so config 0 (0.45 at 16 MiB) takes its place on the
  // front against the pool, beside config 3 (0.15 at 32 MiB).
  CHECK(front_configs(html, "popin.blurry_fraction_mean", "pool_MiB") == std::set<int>{0, 3});
}

TEST_CASE("sweep report: the same inputs give the same bytes, in any row order") {
  auto [meta, rows] = two_by_two();
  rows[2]["status"] = "error";
  rows[2]["error"] = "first";
  rows[5]["status"] = "error";
  rows[5]["error"] = "second";
  const std::string a = vtsim::sweep_report_html(meta, rows);
  CHECK(a == vtsim::sweep_report_html(meta, rows));
  std::reverse(rows.begin(), rows.end());
  CHECK(a == vtsim::sweep_report_html(meta, rows));
}

TEST_CASE("sweep report: no axes, one config, and nothing at all do not crash") {
  auto [meta, rows] = grid_sweep({}, 1, [](std::size_t, std::size_t, const json&) { return popin_summary(0.2, 1); });
  REQUIRE(meta["configs"].size() == 1);
  std::string html = vtsim::sweep_report_html(meta, rows);
  CHECK(contains(html, "1 config × 1 trace = 1 row"));
  CHECK(contains(html, "aria-label=\"popin.blurry_fraction_mean\""));  // a bar chart per metric
  CHECK(contains(html, "No cost varies"));

  // An explicit list of configs (no grid axes): bars, and the front still drawn.
  meta["configs"] = json::array();
  rows.clear();
  for (int c = 0; c < 3; ++c) {
    const json values = {{"vt.pool_pages", std::to_string(256 << c)}, {"disk.preset", "\"hdd\""}};
    meta["configs"].push_back({{"config", c}, {"values", values}, {"cost", {{"pool_MiB", 16 << c}}}});
    rows.push_back({{"row", c}, {"config", c}, {"trace", 0}, {"values", values}, {"status", "ok"},
                    {"summary", popin_summary(0.3 - 0.1 * c, 1)}});
  }
  meta["axis_keys"] = {"vt.pool_pages", "disk.preset"};
  html = vtsim::sweep_report_html(meta, rows);
  CHECK(contains(html, "#2: 1024, hdd"));
  CHECK(front_configs(html, "popin.blurry_fraction_mean", "pool_MiB") == std::set<int>{0, 1, 2});

  CHECK(contains(vtsim::sweep_report_html(json::object(), {}), "0 configs × 0 traces = 0 rows"));
  CHECK(contains(vtsim::sweep_report_html(json::array({1, 2}), {json(3), json::object()}), "</html>"));
  const json far = {{"config", 1000000000000LL}, {"trace", 0}, {"status", "ok"}, {"summary", json::object()}};
  CHECK(contains(vtsim::sweep_report_html(json::object(), {far}), "0 configs × 0 traces"));  // a corrupt index: ignored
}

TEST_CASE("sweep report: a missing metric path or a non-number renders n/a") {
  const auto [meta, rows] =
      grid_sweep({{"vt.pool_pages", {"256", "512"}}}, 2, [](std::size_t, std::size_t, const json&) { return popin_summary(0.2, 1); },
                 {"no.such.path", "popin", "popin.blurry_fraction_mean.deeper"});
  const std::string html = vtsim::sweep_report_html(meta, rows);
  for (const char* m : {"no.such.path", "popin", "popin.blurry_fraction_mean.deeper"}) {
    const std::string open = std::string("<table class=\"breakdown\" data-metric=\"") + m + "\">";
    REQUIRE(contains(html, open));
    const std::size_t at = html.find(open);
    const std::string table = html.substr(at, html.find("</table>", at) - at);
    std::size_t na = 0;  // 2 configs × (2 traces + the mean), all n/a
    const std::string cell = "<td class=\"na\">n/a</td>";
    for (std::size_t p = table.find(cell); p != std::string::npos; p = table.find(cell, p + 1)) ++na;
    CHECK(na == 6);
  }
  CHECK(contains(html, "n/a for every config"));
}

TEST_CASE("sweep report: more than six lines become a band, an outlier is clipped and marked") {
  const auto [meta, rows] =
      grid_sweep({{"vt.pool_pages", {"256", "512", "1024", "2048"}}, {"upload.tiles_per_frame", {"1", "2", "3", "4", "5", "6", "7", "8"}}},
                 1, [](std::size_t c, std::size_t, const json&) { return popin_summary(c == 31 ? 50.0 : 0.01 * static_cast<double>(c % 5 + 1), 1); });
  const std::string html = vtsim::sweep_report_html(meta, rows);
  CHECK(contains(html, "mean of 8 combinations"));  // over the pool: one line per tiles value, 8
  CHECK(contains(html, "min–max"));
  CHECK(contains(html, "off the scale: max 50"));
  CHECK(contains(html, "vt.pool_pages (log scale)"));
}

TEST_CASE("sweep report: metrics.opt rows add each trace's pool miss-ratio curve beside the live ratio per pool size") {
  const auto [meta, rows] = grid_sweep({{"vt.pool_pages", {"256", "512"}}}, 2, [](std::size_t c, std::size_t t, const json& v) {
    json s = popin_summary(0.1 * static_cast<double>(c + 1), 1.0);
    const auto pages = static_cast<std::uint64_t>(std::stoull(v["vt.pool_pages"].get<std::string>()));
    if (t == 0)  // only trace 0 recorded its accesses
      s["vt"] = {{"pool_pages", pages},
                 {"pool", {{"hits", 90}, {"misses", 10 * (2 - c)},
                           {"bounds", {{"mrc", {{"unit", "pages"}, {"capacity", {0, 256, 512, 768}}, {"miss_ratio", {1.0, 0.2, 0.1, 0.05}}}}}}}}};
    return s;
  });
  const std::string html = vtsim::sweep_report_html(meta, rows);
  CHECK(html.find("VT pool: miss-ratio curves") != std::string::npos);
  CHECK(html.find("Pool miss ratio: walk duration_s=20 #0") != std::string::npos);
  CHECK(html.find("Pool miss ratio: walk duration_s=20 #1") == std::string::npos);
  // A row whose bounds lack the curve (not as vtsim writes it): that trace has no chart, no crash.
  auto broken = rows;
  for (auto& r : broken)
    if (r["summary"].contains("vt")) r["summary"]["vt"]["pool"]["bounds"].erase("mrc");
  CHECK(vtsim::sweep_report_html(meta, broken).find("Pool miss ratio") == std::string::npos);
  // Without bounds in any row: no such section.
  const auto [meta2, rows2] = two_by_two();
  CHECK(vtsim::sweep_report_html(meta2, rows2).find("miss-ratio curves") == std::string::npos);
}

TEST_CASE("sweep report: only metrics with a direction are coloured, and a pool-starved config is not best at pops, disk or hit ratio") {
  // Config 0 starves (blurry 0.65, few pops, little disk, a high RAM hit ratio), config 1 does not.
  const auto [meta, rows] = grid_sweep({{"vt.pool_pages", {"64", "1024"}}}, 1,
                                       [](std::size_t c, std::size_t, const json&) {
                                         json s = popin_summary(c == 0 ? 0.65 : 0.02, 1);
                                         s["popin"]["visible_pops"] = c == 0 ? 10 : 5000;
                                         s["bandwidth"]["disk_read_MBps"] = c == 0 ? 1.0 : 9.0;
                                         s["cache"]["ram_hit_ratio"] = c == 0 ? 0.9 : 0.4;
                                         return s;
                                       },
                                       {"popin.blurry_fraction_mean", "popin.visible_pops", "bandwidth.disk_read_MBps",
                                        "cache.ram_hit_ratio"});
  const std::string html = vtsim::sweep_report_html(meta, rows);
  const auto table = [&](const std::string& m) {
    const std::string open = "<table class=\"breakdown\" data-metric=\"" + m + "\">";
    const std::size_t at = html.find(open);
    return at == std::string::npos ? std::string() : html.substr(at, html.find("</table>", at) - at);
  };
  CHECK(contains(table("popin.blurry_fraction_mean"), "class=\"best\""));
  for (const char* m : {"popin.visible_pops", "bandwidth.disk_read_MBps", "cache.ram_hit_ratio"}) {
    CAPTURE(m);
    REQUIRE_FALSE(table(m).empty());
    CHECK_FALSE(contains(table(m), "class=\"best\""));
    CHECK_FALSE(contains(table(m), "background:"));
    CHECK(contains(html, std::string("<h3 id=\"trace-") + m + "\">" + m + "</h3>\n<p class=\"note\">no better direction"));
  }
}

TEST_CASE("sweep report: the Pareto fronts are taken among the configs that meet the blur bound") {
  // Config 0 is cheapest and quickest to sharp but 65 % blurry; config 1 is 4 % blurry.
  auto [meta, rows] = grid_sweep({{"vt.pool_pages", {"64", "1024"}}}, 1, [](std::size_t c, std::size_t, const json&) {
    json s = popin_summary(c == 0 ? 0.65 : 0.04, 1);
    s["popin"]["time_to_sharp_s"]["mean"] = c == 0 ? 0.1 : 0.8;
    return s;
  });
  meta["blur_bound"] = 0.05;
  std::string html = vtsim::sweep_report_html(meta, rows);
  CHECK(contains(html, "at most <b>0.05</b> (the spec's <code>blur_bound</code>): <b>1 of 2</b> configs meet it"));
  // One config left: no cost varies among those that meet the bound, so no front at all.
  CHECK(front_configs(html, "popin.time_to_sharp_s.mean", "pool_MiB") == std::set<int>{-1});
  meta["blur_bound"] = 0.7;  // both compete: the blurry one is on the front (cheapest)
  html = vtsim::sweep_report_html(meta, rows);
  CHECK(front_configs(html, "popin.time_to_sharp_s.mean", "pool_MiB") == std::set<int>{0});
}

TEST_CASE("sweep report: a trace without a time to sharp (null) is left out of the means, not averaged as 0") {
  // Trace 0 has events (2 s and 4 s), trace 1 none (null): the means are 2 and 4, not 1 and 2.
  const auto [meta, rows] = grid_sweep({{"vt.pool_pages", {"256", "512"}}}, 2, [](std::size_t c, std::size_t t, const json&) {
    json s = popin_summary(0.02, 1);
    s["popin"]["time_to_sharp_s"]["mean"] = t == 0 ? json(c == 0 ? 2.0 : 4.0) : json();
    return s;
  });
  const std::string html = vtsim::sweep_report_html(meta, rows);
  const std::string open = "<table class=\"breakdown\" data-metric=\"popin.time_to_sharp_s.mean\">";
  REQUIRE(contains(html, open));
  const std::size_t at = html.find(open);
  const std::string table = html.substr(at, html.find("</table>", at) - at);
  CHECK(contains(table, "<td class=\"na\">n/a</td><td class=\"best\" style=\"background:hsl(120,65%,84%)\">2</td>"));
  CHECK(contains(table, "<td class=\"na\">n/a</td><td style=\"background:hsl(0,65%,84%)\">4</td>"));
}
