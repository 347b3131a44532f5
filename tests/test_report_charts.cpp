// The report's chart scales and ticks (src/sim/report/svg_chart.h), the side-by-side report
// (report_runs.h) and the replay report's contents (report_html.h).
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "sim/report/report_html.h"
#include "sim/report/report_runs.h"
#include "sim/report/svg_chart.h"
#include "test_util.h"

namespace {

bool report_test_contains(const std::string& s, const std::string& sub) { return s.find(sub) != std::string::npos; }

}  // namespace

TEST_SUITE("report") {
  TEST_CASE("nice_scale: round ticks covering the range") {
    const vtsim::ChartScale a = vtsim::nice_scale(0, 3.8);
    CHECK(a.lo == 0);
    CHECK(a.step == 1);
    CHECK(a.hi == 4);
    CHECK(a.ticks == std::vector<double>{0, 1, 2, 3, 4});
    const vtsim::ChartScale b = vtsim::nice_scale(0, 0.9);
    CHECK(b.step == doctest::Approx(0.25));
    CHECK(b.hi == doctest::Approx(1.0));
    CHECK(b.ticks.size() == 5);
    const vtsim::ChartScale c = vtsim::nice_scale(-3, 7);
    CHECK(c.step == doctest::Approx(2.5));
    CHECK(c.lo == doctest::Approx(-5));
    CHECK(c.hi == doctest::Approx(7.5));
    const vtsim::ChartScale flat = vtsim::nice_scale(0, 0);
    CHECK(flat.lo == 0);
    CHECK(flat.hi == 1);
  }

  TEST_CASE("robust_scale: a start-up spike does not set the scale") {
    // 600 frames at a steady 3.8 MB/s after 10 frames at 500 MB/s (issue 26 §3).
    std::vector<double> v(10, 500.0);
    v.insert(v.end(), 600, 3.8);
    const vtsim::ChartScale sc = vtsim::robust_scale(v);
    CHECK(sc.clipped);
    CHECK(sc.max == 500);
    CHECK(sc.lo == 0);
    CHECK(sc.hi == 6);  // 1.25 × 3.8 = 4.75, rounded up to a tick (step 2)
    // Without a spike the maximum sets the top.
    const vtsim::ChartScale plain = vtsim::robust_scale({1, 2, 3, 4, 7});
    CHECK_FALSE(plain.clipped);
    CHECK(plain.hi == 8);
    CHECK(plain.max == 7);
    // Empty and non-finite input: a default 0..1 scale.
    CHECK(vtsim::robust_scale({}).hi == 1);
    CHECK(vtsim::robust_scale({std::nan(""), INFINITY}).hi == 1);
  }

  TEST_CASE("format_tick: decimals from the step, no 0.01667") {
    CHECK(vtsim::format_tick(20, 5) == "20");
    CHECK(vtsim::format_tick(0.25, 0.25) == "0.25");
    CHECK(vtsim::format_tick(0.5, 0.25) == "0.50");
    CHECK(vtsim::format_tick(7.5, 2.5) == "7.5");
    CHECK(vtsim::format_tick(1e-12, 0.1) == "0.0");
    CHECK(vtsim::format_tick(-5, 2.5) == "-5.0");
    CHECK(vtsim::format_tick(1500, 500) == "1500");
  }

  TEST_CASE("time_chart_svg: legend below the plot, clipped values noted") {
    vtsim::TimeChart c;
    c.title = "Disk read";
    c.y_unit = "MB/s";
    for (int i = 0; i < 100; ++i) c.x.push_back(i / 10.0);
    std::vector<double> y(100, 3.8);
    y[0] = 500;
    c.lines.push_back({"disk <read>", "#123456", y});
    const std::string svg = vtsim::time_chart_svg(c, 600);
    CHECK(svg.rfind("<svg", 0) == 0);
    CHECK(report_test_contains(svg, "disk &lt;read&gt;"));
    CHECK(report_test_contains(svg, "off the scale: max 500 MB/s at 0 s"));
    CHECK(report_test_contains(svg, ">6</text>"));  // the top tick
    CHECK_FALSE(report_test_contains(svg, ">500</text>"));
    CHECK(vtsim::time_chart_svg(vtsim::TimeChart{}, 600).empty());
  }

  TEST_CASE("bar_chart_svg and flatten_scalars") {
    const std::string svg = vtsim::bar_chart_svg("t", "s", {"a", "b"}, {{"x", "#000", {1, 2}}}, 500);
    CHECK(report_test_contains(svg, ">2</text>"));
    const nlohmann::json j = {{"a", 1}, {"b", {{"c", "x"}, {"per_level", {{{"level", 3}, {"v", 2.5}}}}}}, {"long", std::vector<int>(20, 1)}};
    const auto f = vtsim::flatten_scalars(j);
    REQUIRE(f.size() == 4);  // the long array is left out
    CHECK(f[0].first == "a");
    CHECK(f[1].first == "b.c");
    CHECK(f[2].first == "b.per_level.level3.level");
    CHECK(f[3].first == "b.per_level.level3.v");
    CHECK(f[3].second == 2.5);
  }

  TEST_CASE("html_runs_report: every metric side by side, differences marked") {
    const nlohmann::json a = {{"vtsim_version", "1"}, {"system", "clipmap"}, {"latency_ms", {{"p50", 10.0}}}, {"config", {{"k", 1}}}};
    nlohmann::json b = a;
    b["latency_ms"]["p50"] = 15.0;
    const std::string h = vtsim::html_runs_report({{"base", a, {}}, {"new <b>", b, {}}});
    CHECK(report_test_contains(h, "new &lt;b&gt;"));
    CHECK(report_test_contains(h, "<tr class=\"diff\"><th>latency_ms.p50</th>"));
    CHECK(report_test_contains(h, "<td class=\"num d worse\">15 (+50.0 %)</td>"));  // latency: lower is better
    CHECK(report_test_contains(h, "<tr><th>config.k</th>"));
    CHECK(h.find("config.k") < h.find("latency_ms.p50"));  // config rows first
  }

  TEST_CASE("html_report: the config is shown and the budget drawn") {
    vtsim::MetricsCollector m;
    for (int i = 0; i < 30; ++i) {
      vtsim::FrameRow r;
      r.frame = i;
      r.t_s = i / 60.0;
      r.uploads = static_cast<std::uint32_t>(i % 5);
      m.add_frame(r);
    }
    const nlohmann::json s = {{"system", "clipmap"}, {"trace", {{"name", "w"}, {"fps", 60.0}}}};
    const std::string h = vtsim::html_report(s, m, {{"upload.tiles_per_frame", "16"}, {"disk.preset", "\"hdd\""}});
    CHECK(report_test_contains(h, "budget (upload.tiles_per_frame)"));
    CHECK(report_test_contains(h, "disk.preset = &quot;hdd&quot;"));
    CHECK(report_test_contains(h, "out.id = 'vtsim-check'"));  // the check script is there
    // Without a config argument, the summary's own "config" object (as replays write it: flat keys)
    // is used: the budget line and the run's identity section show it.
    nlohmann::json s2 = s;
    s2["config"] = {{"upload.tiles_per_frame", 8}};
    const std::string h2 = vtsim::html_report(s2, m);
    CHECK(report_test_contains(h2, "<th>upload.tiles_per_frame</th><td>8</td>"));
    CHECK(report_test_contains(h2, "budget (upload.tiles_per_frame)"));
  }

  TEST_CASE("vtsim report: runs side by side, bad inputs exit 2 naming the file or flag") {
    const std::string dir = std::filesystem::temp_directory_path().string() + "/vtsim_report_cli";
    std::filesystem::create_directories(dir);
    const std::string a = dir + "/a.json", b = dir + "/b.json", bad = dir + "/bad.json", out = dir + "/runs.html", err = dir + "/err.txt";
    std::ofstream(a) << R"({"vtsim_version":"x","system":"clipmap","latency_ms":{"p50":10}})";
    std::ofstream(b) << R"({"vtsim_version":"x","system":"vt","latency_ms":{"p50":12}})";
    std::ofstream(bad) << R"({"schema":"vtsim-bench/1"})";
    auto r = vtsim::test::run_vtsim_capture("report " + a + " " + b + " --names one,two -o " + out, err);
    CHECK(r.code == 0);
    const std::string html = vtsim::test::slurp(out);
    CHECK(report_test_contains(html, "12 (+20.0 %)"));
    CHECK(report_test_contains(html, "<th>two</th>"));
    r = vtsim::test::run_vtsim_capture("report " + a + " " + bad + " -o " + out, err);
    CHECK(r.code == 2);
    CHECK(report_test_contains(r.err, "bad.json"));
    r = vtsim::test::run_vtsim_capture("report " + a + " " + b + " --names one -o " + out, err);
    CHECK(r.code == 2);
    CHECK(report_test_contains(r.err, "--names"));
    r = vtsim::test::run_vtsim_capture("report " + a + " -o " + dir + "/no/such/dir/x.html", err);
    CHECK(r.code == 2);
    CHECK(report_test_contains(r.err, "-o"));
    // Frames CSVs add charts over time; a bad one is refused naming its line.
    const std::string fa = dir + "/a.csv", fb = dir + "/b.csv";
    std::ofstream(fa) << "frame,t_s,disk_bytes,upload_bytes,blurry_fraction,ram_bytes\n0,0,100,100,0.5,1048576\n1,0.1,0,0,0.25,2097152\n";
    std::ofstream(fb) << "t_s,disk_bytes,upload_bytes,blurry_fraction,ram_bytes\n0,1,1,0.5,0\n0.1,x,1,0.5,0\n";
    r = vtsim::test::run_vtsim_capture("report " + a + " " + b + " --frames " + fa + "," + fa + " -o " + out, err);
    CHECK(r.code == 0);
    CHECK(report_test_contains(vtsim::test::slurp(out), "aria-label=\"RAM cache occupancy\""));
    r = vtsim::test::run_vtsim_capture("report " + a + " " + b + " --frames " + fa + "," + fb + " -o " + out, err);
    CHECK(r.code == 2);
    CHECK(report_test_contains(r.err, "b.csv:3"));
    CHECK(report_test_contains(r.err, "disk_bytes"));
    r = vtsim::test::run_vtsim_capture("report " + a + " -o -", err);
    CHECK(r.code == 0);
    CHECK(r.out.rfind("<!doctype html>", 0) == 0);
  }
}
