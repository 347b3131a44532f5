#pragma once
// Metric-by-metric comparison of two vtsim JSON documents — replay summaries (docs/metrics.md) or
// benchmark results (schema vtsim-bench/1, docs/bench.md) — for CI regression checks
// (docs/compare.md). Every leaf of the base document is matched with the same key in the new one
// and judged against a per-key tolerance and direction; `vtsim compare` prints the table and exits
// 0 (same or within tolerance), 1 (a regression) or 2 (bad input).
//
// Keys are flattened paths: object members joined with '.', array elements as "key[i]" plus the
// array's length as "key[]"; arrays of per-level objects by level ("bandwidth.per_level[level=3]
// .disk_read_bytes"); a benchmark's `results` array by case name ("results.get_hit90_zipf.median"). Pure functions over nlohmann::json; thread-compatible.
#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sim/run/metric_path.h"

namespace vtsim {

// Which way a metric is better. lower/higher: a change beyond tolerance the wrong way is a
// regression, the right way an improvement. both: any change beyond tolerance is a regression
// (bandwidth: more costs IO, less means something stopped loading). info: reported, never fails.
// auto_: from the document (a benchmark result's "better" field), else both.
enum class Better { lower, higher, both, info, auto_ };
const char* to_string(Better b);
// "lower" | "higher" | "both" | "info" | "auto"; nullopt otherwise.
std::optional<Better> parse_better(const std::string& s);

// A resolved tolerance: a change d = new − base passes when |d| <= max(abs, rel·|base|).
// abs = rel = 0 is exact.
struct Tolerance {
  double abs = 0.0;  // in the metric's own unit
  double rel = 0.0;  // fraction of |base|
  Better better = Better::both;
  bool ignore = false;  // not compared at all (and may be missing from the new document)
};

// A rule maps a key pattern to tolerance fields; '*' matches any run of characters, dots and
// brackets included. Unset fields fall through to the next matching rule (the defaults last).
struct ToleranceRule {
  std::string pattern;
  std::optional<double> abs, rel;
  std::optional<Better> better;
  std::optional<bool> ignore;
  std::string origin;  // "default", "--ignore" or "file:line"
};

enum class DocKind { summary, bench };
const char* to_string(DocKind k);

// The built-in rules of a document kind (docs/compare.md lists them): summaries exact (floats
// within kFloatRel/kFloatAbs), the wall-clock sections (`run.*`, `real_clock.*`) ignored unless
// `wall_clock` (then relative 25% bands), the run's identity (config.*, the trace's path, hash and
// poses) info; benchmarks: medians and ratios within 15%, the samples and spreads ignored;
// provenance (version, commit, time, machine, trace name) ignored.
// `real_clock` (either run's clock is real): the metric sections too are wall-clock measurements
// and compare within 25%.
std::vector<ToleranceRule> default_tolerances(DocKind kind, bool wall_clock = false, bool real_clock = false);

// Floats (a JSON number with a fraction or exponent on either side) pass when
// |new − base| <= max(kFloatAbs, kFloatRel·|base|) unless a rule allows more; integers compare
// exactly. Why these values: a simulated run is bit-for-bit reproducible on one build, but another
// compiler or summation order moves a double's last bits (+4e-17 on a blurry fraction); a sum of n
// doubles can drift by ~n·2^-53 relative, which stays under 1e-9 up to 10^7 terms, while no metric
// means anything at 1e-9 of its value (one sample in 10^9). kFloatAbs covers a value near 0,
// where a relative band is empty: 1e-12 of any unit the summaries use (ms, MB/s, fraction, levels).
inline constexpr double kFloatRel = 1e-9;
inline constexpr double kFloatAbs = 1e-12;

// Rules from a TOML file: each table is a key pattern with fields abs, rel (numbers >= 0), better
// (string) and ignore (bool):   ["latency_ms.*"]  rel = 0.05  better = "lower"
// Throws InputError("file:line", ...) naming the bad field.
std::vector<ToleranceRule> load_tolerances(const std::string& path);

// The tolerance of a key: for each field, the most specific matching rule of `user` that sets it
// (a pattern without '*' first, then the one with more literal characters, then the earlier one),
// else of `defaults`, else the Tolerance defaults. `hint` resolves Better::auto_.
Tolerance resolve_tolerance(const std::vector<ToleranceRule>& user, const std::vector<ToleranceRule>& defaults,
                            const std::string& key, Better hint = Better::both);

// Reads and parses a JSON file; throws InputError(path, ...) when unreadable or not JSON.
nlohmann::json load_json_file(const std::string& path);

// The kind of a document: "schema": "vtsim-bench/1" is a benchmark, "vtsim-summary/1" a replay
// summary (as is an object with "vtsim_version" and no "schema": a summary from before the schema).
// Throws InputError(path, ...) otherwise.
DocKind detect_kind(const nlohmann::json& doc, const std::string& path);

enum class Verdict {
  same,     // identical
  within,   // changed within tolerance
  better,   // improved beyond tolerance
  worse,    // regressed beyond tolerance (lower/higher)
  changed,  // changed beyond tolerance where any change counts (both; strings; null vs number)
  info,     // changed beyond tolerance on an info metric
  added,    // only in the new document (a new metric, a longer array)
  removed,  // an array element only in the base document (the length row says so)
  ignored,  // matched an ignore rule
};
const char* to_string(Verdict v);

struct MetricDiff {
  std::string key;
  nlohmann::json base, now;  // scalars (null when absent on that side)
  double delta = 0.0;        // now − base (numbers and booleans)
  double rel = 0.0;          // delta / |base|; 0 when base is 0
  Tolerance tol;
  Verdict verdict = Verdict::same;
};

struct CompareOptions {
  std::vector<ToleranceRule> rules;  // consulted before default_tolerances(kind, wall_clock)
  bool strict = false;               // improvements, added and removed keys also fail
  bool wall_clock = false;           // also compare the wall-clock sections (run.*, real_clock.*)
  bool exact_floats = false;         // no float tolerance (kFloatRel, kFloatAbs)
};

struct CompareReport {
  DocKind kind = DocKind::summary;
  std::string base_path, new_path;
  std::vector<MetricDiff> rows;  // every leaf, base order, then keys only in the new document
  // What a reader must know before trusting the rows: the two runs' configs or traces differ
  // (naming the keys), a side has no config (an older summary), real-clock figures. Never fails.
  std::vector<std::string> notes;
  std::size_t count(Verdict v) const;
  // A regression: a worse or changed row; with strict also better, added or removed rows.
  bool failed(bool strict) const;
};

// Compares two parsed documents. Throws InputError naming the file and key when they are not the
// same kind or schema (summaries: the same "vtsim-summary/N"), when a key of the base (not ignored) is missing from the new document, or
// when a key holds different types (object, array, string, number) on the two sides.
CompareReport compare_documents(const nlohmann::json& base, const std::string& base_path, const nlohmann::json& now,
                                const std::string& new_path, const CompareOptions& opt);

// The keys of a summary that say what the run was rather than what it measured: config.*,
// trace.path, trace.content_hash, trace.poses, trace.poses_duration_s. A difference is reported
// (info and a note), never a regression; one side lacking such a key is not an error.
bool is_identity_key(const std::string& key);

// The table a person reads: changed rows (all rows with `all`), the notes, then a one-line verdict.
std::string format_report(const CompareReport& r, bool all, bool strict);
// The same as JSON: {"base","new","kind","result","counts","notes",rows:[{key,base,new,delta,rel,...}]}.
nlohmann::json report_json(const CompareReport& r, bool all, bool strict);

}  // namespace vtsim
