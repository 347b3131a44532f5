// vtsim compare: tolerances, directions, key matching, bad input (exit 2 naming file and key),
// and the CLI's exit codes.
#include <doctest/doctest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <fstream>
#include <sstream>

#include "sim/compare/compare.h"
#include "sim/run/metric_direction.h"
#include "trace_test_util.h"

using nlohmann::json;
using vtsim::test::contains;
using vtsim::test::input_error;
using vtsim::test::ScratchDir;
using vtsim::test::write_file;

namespace {

using namespace vtsim;

// A small replay summary with the shape `vtsim replay --summary` writes.
json summary() {
  return json::parse(R"({
    "vtsim_version": "0.1.0", "system": "clipmap", "clock": "simulated",
    "trace": {"name": "walk", "frames": 1200, "duration_s": 20.0, "fps": 60.0, "image": [1920, 1080]},
    "bandwidth": {"disk_read_MBps": 3.78, "disk_read_bytes": 75759616,
                  "per_level": [{"level": 0, "disk_read_bytes": 100}, {"level": 3, "disk_read_bytes": 50}],
                  "wasted": {"read_bytes_cancelled_after_io": 0}},
    "latency_ms": {"p50": 16.6, "p95": 33.3, "count": 100, "stages_ms": {"io": {"p50": 0.1, "count": 100}}},
    "popin": {"blurry_fraction_mean": 0.21, "mean_deficit": 0.25, "visible_pops": 1000, "measured_frames": 1200},
    "cache": {"ram_hit_ratio": 0.5, "ram_evictions": 3},
    "throttle": {"frames_throttled": 0, "lod_timeline": [], "policy": "deadline"},
    "run": {"wall_s": 1.0, "frames_per_s": 1200.0, "x_realtime": 20.0, "peak_rss_MB": 100.0}
  })");
}

json bench_doc(double median, double ratio) {
  json r1 = {{"name", "get"},  {"side", "lru_cache"}, {"unit", "ns/op"}, {"better", "lower"}, {"median", median},
             {"min", 1.0},     {"max", 9.0},          {"p10", 2.0},      {"p90", 8.0},        {"mad", 0.1},
             {"samples", {median, median}},           {"reps", 2},       {"ratio", ratio},    {"meets_target", ratio >= 3},
             {"reference", {{"name", "textbook"}, {"median", median * ratio}, {"samples", {1.0}}}}};
  json r2 = {{"name", "scan"}, {"side", "ours"}, {"unit", "MB/s"}, {"better", "higher"}, {"median", 1000.0}, {"reference", nullptr},
             {"ratio", nullptr}};
  return {{"schema", "vtsim-bench/1"}, {"benchmark", "lru"}, {"git", "abc"}, {"time_utc", "2026-11-22T04:44:20Z"},
          {"quick", false}, {"reps", 2}, {"machine", {{"hostname", "vm"}}}, {"params", {{"n", 10}}}, {"results", {r1, r2}}};
}

CompareReport cmp(const json& base, const json& now, CompareOptions opt = {}) {
  return compare_documents(base, "base.json", now, "new.json", opt);
}

const MetricDiff& row(const CompareReport& r, const std::string& key) {
  for (const auto& d : r.rows)
    if (d.key == key) return d;
  FAIL("no row " << key);
  static MetricDiff none;
  return none;
}

}  // namespace

TEST_CASE("compare: glob patterns match whole keys, '*' across dots and brackets") {
  CHECK(glob_match("run.*", "run.wall_s"));
  CHECK_FALSE(glob_match("run.*", "run"));
  CHECK_FALSE(glob_match("run.*", "xrun.wall_s"));
  CHECK(glob_match("*", ""));
  CHECK(glob_match("latency_ms.*count", "latency_ms.stages_ms.io.count"));
  CHECK_FALSE(glob_match("latency_ms.*count", "latency_ms.stages_ms.io.count2"));
  CHECK(glob_match("results.*.samples*", "results.get.reference.samples[3]"));
  CHECK(glob_match("a*b*c", "aXbYbZc"));
  CHECK_FALSE(glob_match("a*b*c", "aXbYbZ"));
  CHECK(glob_match("exact", "exact"));
  CHECK_FALSE(glob_match("exact", "exactly"));
}

TEST_CASE("compare: identical summaries are all same, provenance is ignored") {
  json b = summary(), n = summary();
  n["vtsim_version"] = "9.9.9";
  n["trace"]["name"] = "renamed";
  n["run"]["wall_s"] = 1.1;  // wall clock: not compared by default
  const auto r = cmp(b, n);
  CHECK_FALSE(r.failed(false));
  CHECK_FALSE(r.failed(true));
  CHECK(row(r, "vtsim_version").verdict == Verdict::ignored);
  CHECK(row(r, "trace.name").verdict == Verdict::ignored);
  CHECK(row(r, "run.wall_s").verdict == Verdict::ignored);
  CHECK(row(r, "popin.blurry_fraction_mean").verdict == Verdict::same);
  CHECK(row(r, "trace.image[]").verdict == Verdict::same);
  CHECK(row(r, "trace.image[1]").verdict == Verdict::same);
  CHECK(r.count(Verdict::same) + r.count(Verdict::ignored) + r.count(Verdict::within) == r.rows.size());
}

TEST_CASE("compare: simulated metrics are exact with a direction") {
  json b = summary();
  SUBCASE("more blur is worse") {
    json n = summary();
    n["popin"]["blurry_fraction_mean"] = 0.2100001;
    const auto r = cmp(b, n);
    CHECK(row(r, "popin.blurry_fraction_mean").verdict == Verdict::worse);
    CHECK(row(r, "popin.blurry_fraction_mean").delta == doctest::Approx(1e-7));
    CHECK(r.failed(false));
  }
  SUBCASE("less blur is better: passes unless strict") {
    json n = summary();
    n["popin"]["blurry_fraction_mean"] = 0.2;
    const auto r = cmp(b, n);
    CHECK(row(r, "popin.blurry_fraction_mean").verdict == Verdict::better);
    CHECK_FALSE(r.failed(false));
    CHECK(r.failed(true));
  }
  SUBCASE("higher latency is worse, lower better; a count changes both ways") {
    json n = summary();
    n["latency_ms"]["p95"] = 50.0;
    n["latency_ms"]["p50"] = 10.0;
    n["latency_ms"]["stages_ms"]["io"]["count"] = 99;
    const auto r = cmp(b, n);
    CHECK(row(r, "latency_ms.p95").verdict == Verdict::worse);
    CHECK(row(r, "latency_ms.p50").verdict == Verdict::better);
    CHECK(row(r, "latency_ms.stages_ms.io.count").verdict == Verdict::changed);
  }
  SUBCASE("bandwidth changes fail both ways") {
    for (double v : {3.7, 3.9}) {
      json n = summary();
      n["bandwidth"]["disk_read_MBps"] = v;
      const auto r = cmp(b, n);
      CHECK(row(r, "bandwidth.disk_read_MBps").verdict == Verdict::changed);
      CHECK(r.failed(false));
    }
  }
  SUBCASE("hit ratio and visible pops: no direction (a starved pool raises the one and lowers the other)") {
    for (double v : {0.4, 0.6}) {
      json n = summary();
      n["cache"]["ram_hit_ratio"] = v;
      CHECK(row(cmp(b, n), "cache.ram_hit_ratio").verdict == Verdict::changed);
    }
    json n = summary();
    n["popin"]["visible_pops"] = 800;
    CHECK(row(cmp(b, n), "popin.visible_pops").verdict == Verdict::changed);
  }
  SUBCASE("strings compare exactly") {
    json n = summary();
    n["throttle"]["policy"] = "none";
    CHECK(row(cmp(b, n), "throttle.policy").verdict == Verdict::changed);
  }
  SUBCASE("byte counts above 2^53 are compared exactly") {
    b["bandwidth"]["disk_read_bytes"] = std::uint64_t{1} << 60;
    json n = b;
    n["bandwidth"]["disk_read_bytes"] = (std::uint64_t{1} << 60) + 1;
    const auto r = cmp(b, n);
    CHECK(row(r, "bandwidth.disk_read_bytes").verdict == Verdict::changed);
    CHECK(row(r, "bandwidth.disk_read_bytes").delta == 1.0);
  }
  SUBCASE("null (a NaN written by a summary) against a number is a change") {
    json n = summary();
    n["popin"]["mean_deficit"] = nullptr;
    CHECK(row(cmp(b, n), "popin.mean_deficit").verdict == Verdict::changed);
  }
}

TEST_CASE("compare: timings use relative bands with --wall-clock") {
  const json b = summary();
  json n = summary();
  n["run"]["wall_s"] = 1.3;
  n["run"]["x_realtime"] = 14.0;
  n["run"]["frames_per_s"] = 1500.0;
  CompareOptions wall;
  wall.wall_clock = true;
  auto r = cmp(b, n, wall);
  CHECK(row(r, "run.wall_s").verdict == Verdict::worse);
  CHECK(row(r, "run.x_realtime").verdict == Verdict::worse);  // -30%
  CHECK(row(r, "run.frames_per_s").verdict == Verdict::within);   // +25% is on the band's edge
  CompareOptions opt = wall;
  opt.rules.push_back({.pattern = "run.*", .abs = {}, .rel = {}, .better = {}, .ignore = true, .origin = "--ignore"});
  r = cmp(b, n, opt);
  CHECK(row(r, "run.wall_s").verdict == Verdict::ignored);
  CHECK_FALSE(r.failed(true));
}

TEST_CASE("compare: per-level rows pair by level, arrays report their length") {
  json b = summary(), n = summary();
  n["bandwidth"]["per_level"] = json::parse(R"([{"level": 3, "disk_read_bytes": 50}, {"level": 5, "disk_read_bytes": 7}])");
  const auto r = cmp(b, n);
  CHECK(row(r, "bandwidth.per_level[]").verdict == Verdict::same);  // 2 and 2
  CHECK(row(r, "bandwidth.per_level[level=3].disk_read_bytes").verdict == Verdict::same);
  CHECK(row(r, "bandwidth.per_level[level=0].disk_read_bytes").verdict == Verdict::removed);
  CHECK(row(r, "bandwidth.per_level[level=5].disk_read_bytes").verdict == Verdict::added);
  CHECK_FALSE(r.failed(false));
  CHECK(r.failed(true));

  n = summary();
  n["throttle"]["lod_timeline"] = json::parse(R"([{"frame": 3, "to": 2}])");
  const auto r2 = cmp(b, n);
  CHECK(row(r2, "throttle.lod_timeline[]").verdict == Verdict::changed);
  CHECK(row(r2, "throttle.lod_timeline[0].frame").verdict == Verdict::added);
  CHECK(r2.failed(false));
}

TEST_CASE("compare: a key added in the new document is reported, not fatal") {
  json n = summary();
  n["popin"]["new_metric"] = 1.0;
  const auto r = cmp(summary(), n);
  CHECK(row(r, "popin.new_metric").verdict == Verdict::added);
  CHECK_FALSE(r.failed(false));
  CHECK(r.failed(true));
}

TEST_CASE("compare: bad input names the file and the key") {
  const json b = summary();
  json n = summary();
  n["popin"].erase("mean_deficit");
  std::string e = input_error([&] { cmp(b, n); });
  CHECK(contains(e, "new.json"));
  CHECK(contains(e, "'popin.mean_deficit' is missing"));

  n = summary();
  n.erase("cache");
  e = input_error([&] { cmp(b, n); });
  CHECK(contains(e, "new.json: key 'cache.ram_evictions' is missing (the base base.json has it)"));

  n = summary();
  n["run"].erase("wall_s");  // missing but ignored: fine
  CompareOptions opt;
  opt.rules.push_back({.pattern = "run.*", .abs = {}, .rel = {}, .better = {}, .ignore = true, .origin = "--ignore"});
  CHECK_NOTHROW(cmp(b, n, opt));

  n = summary();
  n["popin"]["visible_pops"] = "many";
  e = input_error([&] { cmp(b, n); });
  CHECK(contains(e, "new.json: key 'popin.visible_pops' is a string, but a number in the base base.json"));

  n = summary();
  n["latency_ms"] = json::array();
  e = input_error([&] { cmp(b, n); });
  CHECK(contains(e, "'latency_ms' is an array, but an object"));

  e = input_error([&] { cmp(b, bench_doc(1.0, 3.0)); });
  CHECK(contains(e, "new.json: is a benchmark JSON, but the base base.json is a summary JSON"));

  e = input_error([&] { cmp(json::array(), b); });
  CHECK(contains(e, "base.json: not a vtsim summary or benchmark JSON"));
  e = input_error([&] { cmp(b, json{{"foo", 1}}); });
  CHECK(contains(e, "new.json: not a vtsim summary"));
  e = input_error([&] { cmp(b, json{{"vtsim_version", "1"}, {"run", json::object()}}); });
  CHECK(contains(e, "new.json: key 'trace' is missing"));

  json nb = bench_doc(1.0, 3.0);
  nb["schema"] = "vtsim-bench/2";
  e = input_error([&] { cmp(bench_doc(1.0, 3.0), nb); });
  CHECK(contains(e, "new.json: key 'schema'"));
  nb = bench_doc(1.0, 3.0);
  nb["benchmark"] = "io";
  e = input_error([&] { cmp(bench_doc(1.0, 3.0), nb); });
  CHECK(contains(e, "key 'benchmark'"));
  nb = bench_doc(1.0, 3.0);
  nb["results"][0].erase("name");
  e = input_error([&] { cmp(bench_doc(1.0, 3.0), nb); });
  CHECK(contains(e, "new.json: key 'results[0].name'"));
}

TEST_CASE("compare: benchmark JSONs by case name, direction from the unit") {
  const json b = bench_doc(10.0, 3.0);
  SUBCASE("slower median and lower ratio are worse") {
    const auto r = cmp(b, bench_doc(12.0, 2.5));
    CHECK(row(r, "results.get.median").verdict == Verdict::worse);  // ns/op: lower is better
    CHECK(row(r, "results.get.median").tol.better == Better::lower);
    CHECK(row(r, "results.get.ratio").verdict == Verdict::worse);
    CHECK(row(r, "results.get.reference.median").verdict == Verdict::same);  // 10·3 = 12·2.5
    CHECK(row(r, "results.get.reference.median").tol.better == Better::info);
    CHECK(row(r, "results.get.samples[0]").verdict == Verdict::ignored);
    CHECK(row(r, "results.get.min").verdict == Verdict::ignored);
    CHECK(row(r, "git").verdict == Verdict::ignored);
    CHECK(row(r, "results.get.meets_target").verdict == Verdict::info);
    CHECK(r.failed(false));
  }
  SUBCASE("within 15% passes; faster is better") {
    auto r = cmp(b, bench_doc(11.0, 2.8));
    CHECK(row(r, "results.get.median").verdict == Verdict::within);
    CHECK_FALSE(r.failed(false));
    r = cmp(b, bench_doc(5.0, 6.0));
    CHECK(row(r, "results.get.median").verdict == Verdict::better);
    CHECK(row(r, "results.get.ratio").verdict == Verdict::better);
    CHECK_FALSE(r.failed(false));
  }
  SUBCASE("MB/s: higher is better") {
    json n = bench_doc(10.0, 3.0);
    n["results"][1]["median"] = 800.0;
    const auto r = cmp(b, n);
    CHECK(row(r, "results.scan.median").verdict == Verdict::worse);
    CHECK(row(r, "results.scan.ratio").verdict == Verdict::same);  // null and null
  }
  SUBCASE("reordered cases still pair by name") {
    json n = bench_doc(10.0, 3.0);
    std::swap(n["results"][0], n["results"][1]);
    CHECK(cmp(b, n).count(Verdict::same) == cmp(b, b).count(Verdict::same));
    CHECK_FALSE(cmp(b, n).failed(true));
  }
}

TEST_CASE("compare: tolerance TOML overrides fields and inherits the rest") {
  ScratchDir dir;
  const std::string tol = dir.file("tol.toml");
  write_file(tol, "# CI tolerances\n[\"popin.blurry_fraction_mean\"]\nabs = 0.01\n\n[bandwidth.disk_read_MBps]\nrel = 0.1\n"
                  "better = \"lower\"\n[\"run.*\"]\nignore = true\n");
  const auto rules = load_tolerances(tol);
  REQUIRE(rules.size() == 3);
  const auto first = std::find_if(rules.begin(), rules.end(), [](const auto& x) { return x.pattern == "popin.blurry_fraction_mean"; });
  REQUIRE(first != rules.end());
  CHECK(first->origin == tol + ":3");
  const auto defaults = default_tolerances(DocKind::summary);
  Tolerance t = resolve_tolerance(rules, defaults, "popin.blurry_fraction_mean");
  CHECK(t.abs == 0.01);
  CHECK(t.better == Better::lower);  // from the defaults
  t = resolve_tolerance(rules, defaults, "bandwidth.disk_read_MBps");
  CHECK(t.rel == 0.1);
  CHECK(t.better == Better::lower);
  CHECK(resolve_tolerance(rules, defaults, "run.wall_s").ignore);
  CHECK(resolve_tolerance(rules, default_tolerances(DocKind::summary, true), "run.wall_s").rel == 0.25);
  CHECK(resolve_tolerance({}, defaults, "run.wall_s").ignore);  // wall clock: not compared by default
  // The most specific rule wins: an exact key beats a wildcard, longer literals beat shorter.
  CHECK(resolve_tolerance({}, defaults, "latency_ms.count").better == Better::both);
  CHECK(resolve_tolerance({}, defaults, "latency_ms.p99").better == Better::lower);
  CHECK(resolve_tolerance({}, defaults, "bandwidth.wasted.read_bytes_cancelled_after_io").better == Better::lower);
  CHECK(resolve_tolerance({}, defaults, "some.unknown.key").better == Better::both);
  CHECK(resolve_tolerance({}, defaults, "some.unknown.key").rel == 0.0);

  CompareOptions opt;
  opt.rules = rules;
  json n = summary();
  n["popin"]["blurry_fraction_mean"] = 0.219;
  n["bandwidth"]["disk_read_MBps"] = 3.5;
  n["run"]["wall_s"] = 100.0;
  const auto r = cmp(summary(), n, opt);
  CHECK(row(r, "popin.blurry_fraction_mean").verdict == Verdict::within);
  CHECK(row(r, "bandwidth.disk_read_MBps").verdict == Verdict::within);  // -7.4% within 10%
  CHECK(row(r, "run.wall_s").verdict == Verdict::ignored);
  CHECK_FALSE(r.failed(true));

  write_file(tol, "[\"popin.*\"]\nrel = -1\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":2: 'popin.*': field 'rel' must be a finite number >= 0"));
  write_file(tol, "[\"popin.*\"]\nbetter = \"up\"\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":2: 'popin.*': field 'better'"));
  write_file(tol, "[\"popin.*\"]\nrelative = 0.1\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), "unknown field 'relative'"));
  write_file(tol, "rel = 0.1\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":1:"));
  write_file(tol, "[\"popin.*\"\nrel = 0.1\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":1"));
  CHECK(contains(input_error([&] { load_tolerances(dir.file("absent.toml")); }), "absent.toml"));
  // A pattern with no field, or no pattern, is a mistake, not a rule that changes nothing.
  write_file(tol, "[\"\"]\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":1: '': a pattern with no field does nothing"));
  write_file(tol, "[\"latency_ms.*\"]\nrel = 0.1\n[run.wall_s]\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":3: 'run.wall_s': a pattern with no field"));
  write_file(tol, "[\"zeta.*\"]\n[\"alpha.*\"]\n");  // the first in the file is named, not the first by name
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":1: 'zeta.*': a pattern with no field"));
  write_file(tol, "[\"\"]\nrel = 0.1\n");
  CHECK(contains(input_error([&] { load_tolerances(tol); }), tol + ":2: the key pattern is empty ([\"\"] with field 'rel')"));
}

TEST_CASE("compare: load_json_file names the file and line") {
  ScratchDir dir;
  const std::string p = dir.file("bad.json");
  write_file(p, "{\n  \"a\": 1,\n  \"b\": ]\n}\n");
  const std::string e = input_error([&] { load_json_file(p); });
  CHECK(contains(e, p + ":3: not valid JSON"));
  CHECK(contains(input_error([&] { load_json_file(dir.file("none.json")); }), "none.json: cannot open"));
  write_file(p, "");
  CHECK(contains(input_error([&] { load_json_file(p); }), p + ":1: not valid JSON"));
}

TEST_CASE("compare: a document's shape is bounded — depth, key path, values — and numbers beyond double are bad input") {
  ScratchDir dir;
  const std::string p = dir.file("shape.json");
  // 16 levels are accepted, 17 refused (the walk recurses once per level).
  const auto nested = [](int depth) {
    std::string s = "{\"vtsim_version\":\"0\",\"trace\":{},\"x\":";
    for (int i = 1; i < depth; ++i) s += "[";
    s += "1";
    for (int i = 1; i < depth; ++i) s += "]";
    return s + "}";
  };
  write_file(p, nested(16));
  CHECK_NOTHROW(load_json_file(p));
  write_file(p, nested(17));
  CHECK(contains(input_error([&] { load_json_file(p); }), p + ": nested deeper than 16 levels"));
  write_file(p, nested(3000));  // overflowed the stack (ASan) before the bound
  CHECK(contains(input_error([&] { load_json_file(p); }), "nested deeper than 16 levels"));
  // Keys along a path: 1,024 characters in all.
  write_file(p, "{\"" + std::string(1023, 'k') + "\": 1}");
  CHECK_NOTHROW(load_json_file(p));
  write_file(p, "{\"" + std::string(600, 'k') + "\": {\"" + std::string(500, 'k') + "\": 1}}");
  CHECK(contains(input_error([&] { load_json_file(p); }), "a key path longer than 1024 characters"));
  // 200,000 values.
  std::string many = "[0";
  for (int i = 1; i < 200000; ++i) many += ",0";
  write_file(p, many + "]");
  CHECK_NOTHROW(load_json_file(p));
  write_file(p, many + ",0]");
  CHECK(contains(input_error([&] { load_json_file(p); }), "more than 200000 values"));
  // nlohmann reports 1e400 as out_of_range, not a parse error: still bad input, not an internal error.
  write_file(p, "{\"vtsim_version\":\"0\",\"trace\":{},\"x\":1e400}");
  CHECK(contains(input_error([&] { load_json_file(p); }), p + ": not valid JSON (") );
  CHECK(contains(input_error([&] { load_json_file(p); }), "number overflow"));
}

TEST_CASE("compare: inputs are checked by descriptor: a FIFO, a directory, a device or a huge file is refused unread") {
  // load_json_file and the tolerance reader (read_toml_entries) both go through read_regular_file.
  ScratchDir dir;
  const std::string fifo = dir.file("fifo"), big = dir.file("big.json");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  // A sparse file one byte over the limit: refused from its size, before any read.
  { std::ofstream(big).put('{'); }
  std::filesystem::resize_file(big, (256u << 20) + 1);
  CHECK(contains(input_error([&] { load_json_file(big); }), big + ": 268435457 bytes, larger than 256 MiB: not a vtsim"));
  std::filesystem::resize_file(big, (16u << 20) + 1);
  CHECK(contains(input_error([&] { load_tolerances(big); }), big + ": 16777217 bytes, larger than 16 MiB"));
  // Read to the end of file, not to the size fstat gives: a /proc file says 0 bytes.
  CHECK(contains(input_error([&] { load_json_file("/proc/self/status"); }), "/proc/self/status:1: not valid JSON"));
  // Exactly at the limit: read, then refused as TOML (NUL bytes), not for its size.
  std::filesystem::resize_file(big, 16u << 20);
  CHECK(contains(input_error([&] { load_tolerances(big); }), "TOML syntax error"));
  for (const auto& load : {std::function<void(const std::string&)>([](const std::string& f) { load_json_file(f); }),
                           std::function<void(const std::string&)>([](const std::string& f) { load_tolerances(f); })}) {
    // A FIFO without a writer would block a plain open: O_NONBLOCK, then the descriptor's type.
    CHECK(contains(input_error([&] { load(fifo); }), fifo + ": not a regular file (a FIFO"));
    CHECK(contains(input_error([&] { load(dir.path().string()); }), dir.path().string() + ": is a directory, not a file"));
    CHECK(contains(input_error([&] { load("/dev/zero"); }), "/dev/zero: not a regular file"));
  }
}

TEST_CASE("compare: report text and JSON") {
  json n = summary();
  n["popin"]["blurry_fraction_mean"] = 0.25;
  const auto r = cmp(summary(), n);
  const std::string text = format_report(r, false, false);
  CHECK(contains(text, "popin.blurry_fraction_mean"));
  CHECK(contains(text, "+0.04 (+19.05%)"));
  CHECK(contains(text, "WORSE"));
  CHECK(contains(text, "REGRESSION: 1 worse"));
  CHECK_FALSE(contains(text, "popin.mean_deficit"));  // same rows only with --all
  CHECK(contains(format_report(r, true, false), "popin.mean_deficit"));
  const json j = report_json(r, false, false);
  CHECK(j["result"] == "regression");
  CHECK(j["counts"]["worse"] == 1);
  REQUIRE(j["rows"].size() == 1);
  CHECK(j["rows"][0]["key"] == "popin.blurry_fraction_mean");
  CHECK(contains(format_report(cmp(summary(), summary()), false, false), "no differences"));
}


TEST_CASE("compare: CLI exit codes 0 same, 1 regression, 2 bad input") {
  ScratchDir dir;
  const std::string base = dir.file("base.json"), same = dir.file("same.json"), worse = dir.file("worse.json"),
                    bad = dir.file("bad.json"), tol = dir.file("tol.toml");
  write_file(base, summary().dump(2));
  json s = summary();
  s["run"]["wall_s"] = 5.0;  // timing noise only
  write_file(same, s.dump());
  s["latency_ms"]["p95"] = 40.0;
  write_file(worse, s.dump());
  s = summary();
  s["trace"] = json::object();
  write_file(bad, s.dump());

  test::CliRun r = test::vtsim_run(dir, "compare " + base + " " + base);
  CHECK(r.code == 0);
  CHECK(contains(r.out, "OK: 0 worse"));
  r = test::vtsim_run(dir, "compare " + base + " " + same);
  CHECK(r.code == 0);  // the wall clock moved: not a regression
  r = test::vtsim_run(dir, "compare --wall-clock " + base + " " + same);
  CHECK(r.code == 1);
  CHECK(contains(r.out, "run.wall_s"));
  r = test::vtsim_run(dir, "compare --wall-clock --ignore 'run.*' " + base + " " + same);
  CHECK(r.code == 0);
  r = test::vtsim_run(dir, "compare --ignore 'run.*' " + base + " " + worse);
  CHECK(r.code == 1);
  CHECK(contains(r.out, "latency_ms.p95"));
  write_file(tol, "[\"run.*\"]\nignore = true\n[latency_ms.p95]\nrel = 0.25\n");
  r = test::vtsim_run(dir, "compare -q --tolerances " + tol + " " + base + " " + worse);
  CHECK(r.code == 0);
  CHECK(r.out.empty());
  r = test::vtsim_run(dir, "compare --json " + base + " " + worse);
  CHECK(r.code == 1);
  CHECK(json::parse(r.out)["result"] == "regression");

  r = test::vtsim_run(dir, "compare " + base + " " + bad);
  CHECK(r.code == 2);
  CHECK(contains(r.err, bad + ": key 'trace.duration_s' is missing (the base " + base + " has it)"));
  r = test::vtsim_run(dir, "compare " + base + " " + dir.file("absent.json"));
  CHECK(r.code == 2);
  CHECK(contains(r.err, "absent.json: cannot open"));
  write_file(tol, "[x]\nbetter = 1\n");
  r = test::vtsim_run(dir, "compare -t " + tol + " " + base + " " + base);
  CHECK(r.code == 2);
  CHECK(contains(r.err, tol + ":2"));
  r = test::vtsim_run(dir, "compare " + base);
  CHECK(r.code == 2);
}

TEST_CASE("compare: a real-clock run's metrics are wall-clock measurements, compared within 25 percent, a simulated run's exactly") {
  const auto doc = [](const char* clock, double p99, int tiles) {
    return json{{"schema", "vtsim-summary/1"}, {"system", "clipmap"}, {"clock", clock}, {"trace", {{"name", "w"}}},
                {"latency_ms", {{"p99", p99}, {"count", tiles}}}};
  };
  // +10 % latency and +10 % tiles: within the band when either run is real-clock ...
  const CompareReport real = cmp(doc("real", 100.0, 1000), doc("real", 110.0, 1100));
  CHECK_FALSE(real.failed(false));
  CHECK(row(real, "latency_ms.p99").verdict == Verdict::within);
  CHECK(row(real, "latency_ms.count").verdict == Verdict::within);
  // ... beyond it (+40 %) a regression ...
  CHECK(cmp(doc("real", 100.0, 1000), doc("real", 140.0, 1000)).failed(false));
  // ... and in the simulated clock any change is one.
  CHECK(cmp(doc("sim", 100.0, 1000), doc("sim", 110.0, 1000)).failed(false));
  CHECK(row(cmp(doc("sim", 100.0, 1000), doc("sim", 100.0, 1001)), "latency_ms.count").verdict == Verdict::changed);
}

TEST_CASE("compare: a lower latency is not better when the served fraction fell or more tiles were throttled") {
  // HDD against NVMe: p95 716.7 -> 533.3 ms while fewer requests were served and 168,704 throttled.
  json b = summary();
  b["latency_ms"]["p95"] = 716.7;
  b["latency_ms"]["served_fraction"] = 0.98;
  b["throttle"]["requests_throttled"] = 0;
  json n = b;
  n["latency_ms"]["p95"] = 533.3;
  SUBCASE("served fraction unchanged: better") {
    const auto r = cmp(b, n);
    CHECK(row(r, "latency_ms.p95").verdict == Verdict::better);
    for (const std::string& note : r.notes) CHECK_FALSE(contains(note, "not better"));
  }
  SUBCASE("served fraction fell: changed, with a note") {
    n["latency_ms"]["served_fraction"] = 0.61;
    const auto r = cmp(b, n);
    CHECK(row(r, "latency_ms.p95").verdict == Verdict::changed);
    CHECK(row(r, "latency_ms.served_fraction").verdict == Verdict::worse);
    REQUIRE_FALSE(r.notes.empty());
    CHECK(r.notes.back() == "1 latency value is lower but not better: the served fraction fell (0.98 -> 0.61) (a latency over "
                            "fewer of the wanted tiles, docs/metrics.md)");
    CHECK(r.failed(false));
  }
  SUBCASE("more tiles throttled: changed") {
    n["throttle"]["requests_throttled"] = 168704;
    const auto r = cmp(b, n);
    CHECK(row(r, "latency_ms.p95").verdict == Verdict::changed);
    CHECK(contains(r.notes.back(), "more tiles were throttled, never requested (0 -> 168704)"));
  }
  SUBCASE("a higher latency is worse whatever the served fraction") {
    n["latency_ms"]["p95"] = 800.0;
    n["latency_ms"]["served_fraction"] = 0.61;
    CHECK(row(cmp(b, n), "latency_ms.p95").verdict == Verdict::worse);
  }
}

TEST_CASE("compare: directions come from the one table of docs/metrics.md") {
  CHECK(metric_direction("latency_ms.p95") == MetricDirection::lower);
  CHECK(metric_direction("latency_ms.served_fraction") == MetricDirection::higher);
  CHECK(metric_direction("latency_ms.count") == MetricDirection::neither);
  CHECK(metric_direction("latency_ms.censored.wait_ms.p95") == MetricDirection::neither);
  CHECK(metric_direction("latency_ms.km.p95") == MetricDirection::lower);
  CHECK(metric_direction("popin.blurry_fraction_mean") == MetricDirection::lower);
  CHECK(metric_direction("popin.visible_pops") == MetricDirection::neither);
  CHECK(metric_direction("bandwidth.disk_read_MBps") == MetricDirection::neither);
  CHECK(metric_direction("bandwidth.wasted.cancelled_before_io") == MetricDirection::lower);
  CHECK(metric_direction("cache.ram_hit_ratio") == MetricDirection::neither);
  CHECK(metric_direction("cache.vram_thrash") == MetricDirection::lower);
  CHECK(metric_direction("vt.pool.hits") == MetricDirection::neither);
  CHECK(is_served_latency_key("latency_ms.stages_ms.io.p95"));
  CHECK(is_served_latency_key("latency_ms.km.p95"));
  CHECK_FALSE(is_served_latency_key("latency_ms.served_fraction"));
  // compare's default rules are the table's: every pattern of it resolves to its direction.
  for (const MetricDirectionRule& d : metric_direction_rules()) {
    CAPTURE(d.pattern);
    std::string key;
    for (const char* ch = d.pattern; *ch; ++ch) key.push_back(*ch == '*' ? 'x' : *ch);
    const Better want = d.direction == MetricDirection::lower    ? Better::lower
                        : d.direction == MetricDirection::higher ? Better::higher
                                                                 : Better::both;
    CHECK(resolve_tolerance({}, default_tolerances(DocKind::summary), key).better == want);
    CHECK(metric_direction(key) == d.direction);
  }
}
