#pragma once
// A sweep spec (docs/sweep.md): traces × configs, read from one TOML file.
//
//   name = "pool-vs-upload"                  # optional, shown in the report
//   config = "base.toml"                     # optional base config file (relative to the spec)
//   set = ["run.system=vt", "scene.kind=town"]      # base overrides, as --set
//   traces = ["traces/walk.csv", "traces/t*.csv"]   # files and globs, relative to the spec
//   generate = ["walk duration_s=600 start_m=30,8"] # generator lines (a generated trace's name)
//   metrics = ["popin.blurry_fraction_mean", "latency_ms.p99"]  # CSV columns (default: a standard set)
//   [grid]                                   # axes: every combination
//   "vt.pool_pages" = [256, 512, 1024]
//   "upload.tiles_per_frame" = [4, 8]
//   [[configs]]                              # or/and an explicit list of config sets
//   "vt.pool_pages" = 256
//
// Config points are the explicit configs (one empty set when there are none) × the grid; the
// grid's first axis (in the file's order) varies slowest. Every point is loaded and validated
// before any replay runs: a bad key or value names spec:line:key.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string_view>
#include <string>
#include <vector>

#include "core/trace.h"
#include "sim/run/metric_path.h"
#include "sim/run/replay_config.h"

namespace vtsim {

struct SweepAxis {
  std::string key;                  // a config key ("vt.pool_pages")
  std::vector<std::string> values;  // each as TOML writes it ("256", "\"hdd\"", "0.5")
  long long line = 0;
};

struct SweepTraceSource {
  std::string text;     // as written: a file path (after glob expansion) or a generator line
  bool generated = false;
  long long line = 0;
};

struct SweepPoint {
  int index = 0;                                             // config index, in point order
  std::vector<std::pair<std::string, std::string>> values;   // key, TOML value: the point's own keys
  ReplayConfig cfg;                                          // base + values, validated
};

// `vtsim tune`'s section:
//   [tune]
//   constraints = ["popin.blurry_fraction_p99 <= 0.02", "latency_ms.p99 <= 200"]  # on every trace
//   costs = ["vt.pool_pages", "upload.tiles_per_frame"]  # grid axes that cost; default: all
// A cost axis lists its values from cheapest to dearest.
struct TuneConstraint {
  std::string metric;   // dotted summary path
  bool at_most = true;  // metric <= bound (else >=)
  double bound = 0;
  std::string text;     // as written
  long long line = 0;   // its line in the spec
};
struct TuneSpec {
  bool present = false;
  std::vector<TuneConstraint> constraints;
  std::vector<std::string> costs;
  long long line = 0;
};

struct SweepSpec {
  std::string path;                       // the spec file
  std::string name;
  std::string base_config;                // resolved path, or empty
  std::vector<std::string> base_sets;
  std::vector<SweepTraceSource> traces;   // in spec order: files (globs sorted), then generators
  std::vector<SweepAxis> grid;
  std::vector<std::vector<std::pair<std::string, std::string>>> configs;  // explicit sets
  std::vector<std::string> metrics;       // dotted summary paths for the CSV and the report
  long long metrics_line = 0;             // the spec line of `metrics` (0: the default set)
  std::vector<SweepPoint> points;         // configs × grid, validated
  std::vector<std::string> axis_keys;     // every key a point sets, in first-seen order
  std::string base_dump;                  // the base config, every key (identity, not display)
  TuneSpec tune;
  bool allow_repairs = false;             // keep traces whose repairs dropped beyond the policy (trace_io.h)
  double blur_bound = 0.05;               // the report's Pareto fronts: only configs whose mean blurry fraction is at most this
};

// "metric <= 0.02" / "metric >= 0.9"; InputError at `where` otherwise.
TuneConstraint parse_tune_constraint(const std::string& text, const std::string& where);

// Reads, expands and validates a spec. Throws InputError naming spec:line:key.
SweepSpec load_sweep_spec(const std::string& path);

// The default CSV/report metrics (dotted paths into a replay summary).
const std::vector<std::string>& default_sweep_metrics();

// A trace of the spec, loaded (files) or generated. Throws InputError naming the source (also for
// more dropped poses than the repair policy allows: trace_io.h, check_repairs). The repairs made
// are appended to *warnings when given (repair_warnings: one line per kind, naming the file).
Trace load_sweep_trace(const SweepTraceSource& src, std::vector<std::string>* warnings = nullptr, bool allow_repairs = false);


}  // namespace vtsim
