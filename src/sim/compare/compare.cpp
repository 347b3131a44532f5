#include "sim/compare/compare.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>

#include "core/config_table.h"
#include "core/error.h"
#include "core/input_file.h"
#include "sim/run/metric_direction.h"
#include "sim/run/provenance.h"

namespace vtsim {

using nlohmann::json;

const char* to_string(Better b) {
  switch (b) {
    case Better::lower: return "lower";
    case Better::higher: return "higher";
    case Better::both: return "both";
    case Better::info: return "info";
    case Better::auto_: return "auto";
  }
  return "?";
}

std::optional<Better> parse_better(const std::string& s) {
  if (s == "lower") return Better::lower;
  if (s == "higher") return Better::higher;
  if (s == "both") return Better::both;
  if (s == "info") return Better::info;
  if (s == "auto") return Better::auto_;
  return std::nullopt;
}

const char* to_string(DocKind k) { return k == DocKind::summary ? "summary" : "benchmark"; }

const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::same: return "same";
    case Verdict::within: return "within";
    case Verdict::better: return "better";
    case Verdict::worse: return "WORSE";
    case Verdict::changed: return "CHANGED";
    case Verdict::info: return "info";
    case Verdict::added: return "added";
    case Verdict::removed: return "removed";
    case Verdict::ignored: return "ignored";
  }
  return "?";
}

namespace {

ToleranceRule rule(std::string pattern, std::optional<double> rel, std::optional<Better> better,
                   std::optional<bool> ignore = std::nullopt) {
  ToleranceRule r;
  r.pattern = std::move(pattern);
  r.rel = rel;
  r.better = better;
  r.ignore = ignore;
  r.origin = "default";
  return r;
}

constexpr std::optional<double> kExact = 0.0;

}  // namespace

std::vector<ToleranceRule> default_tolerances(DocKind kind, bool wall_clock, bool real_clock) {
  using B = Better;
  if (kind == DocKind::summary) {
    // Simulated metrics are bit-for-bit reproducible (docs/architecture.md: one pipeline, an
    // event queue of integer ticks), so everything but the run's own cost compares exactly.
    // The provenance fields: a version bump, a new commit, another machine or a renamed trace
    // file is not a change in behaviour (trace.frames and trace.duration_s still catch a
    // different trace, and the notes say so).
    std::vector<ToleranceRule> r = {
        rule("vtsim_version", {}, {}, true),  // summaries from before vtsim-summary/1
        rule("provenance.*", {}, {}, true),
        rule("trace.name", {}, {}, true),
        // What the run was: reported (rows and notes), never a regression by itself.
        rule("config.*", {}, B::info),
        rule("trace.path", {}, B::info),
        rule("trace.content_hash", {}, B::info),
        rule("trace.poses", {}, B::info),
        rule("trace.poses_duration_s", {}, B::info),
    };
    if (!wall_clock) {
      // Wall-clock figures differ on every run (a loaded machine: run.wall_s +31.8% on an
      // unchanged build): an exact check would cry wolf. --wall-clock compares them in bands.
      r.push_back(rule("run.*", {}, {}, true));
      r.push_back(rule("real_clock.*", {}, {}, true));
    } else {
      // The machine is shared and single runs swing; a 25% band catches real slowdowns.
      for (auto x : {rule("run.*", 0.25, B::info), rule("run.wall_s", 0.25, B::lower), rule("run.frames_per_s", 0.25, B::higher),
                     rule("run.x_realtime", 0.25, B::higher), rule("run.peak_rss_MB", 0.25, B::lower),
                     rule("real_clock.*", 0.25, B::info)})
        r.push_back(std::move(x));
    }
    // A real-clock run measured its latency, pop-in, bandwidth and even its counts (what arrived
    // by which frame) in wall-clock time: two runs of one build differ, so its metrics compare in
    // the same 25% band as the wall-clock sections; a simulated run's compare exactly.
    const std::optional<double> m_tol = real_clock ? std::optional<double>(0.25) : kExact;
    // Directions: the one table of docs/metrics.md ("Directions", sim/run/metric_direction.h);
    // a metric with none compares both ways (more costs, less means something stopped).
    std::vector<ToleranceRule> metrics;
    for (const MetricDirectionRule& d : metric_direction_rules())
      metrics.push_back(rule(d.pattern, m_tol,
                             d.direction == MetricDirection::lower    ? B::lower
                             : d.direction == MetricDirection::higher ? B::higher
                                                                      : B::both));
    r.insert(r.end(), metrics.begin(), metrics.end());
    return r;
  }
  // Benchmarks (schema vtsim-bench/1): medians and ratios are timings; the per-repetition samples
  // and spreads are noise at the comparison's scale; provenance and machine are not metrics.
  return {
      rule("git", {}, {}, true),
      rule("time_utc", {}, {}, true),
      rule("machine.*", {}, {}, true),
      rule("reps", kExact, B::info),
      rule("warmup", kExact, B::info),
      rule("results.*.samples*", {}, {}, true),
      rule("results.*.pair_ratios*", {}, {}, true),
      rule("results.*.min", {}, {}, true),
      rule("results.*.max", {}, {}, true),
      rule("results.*.p10", {}, {}, true),
      rule("results.*.p90", {}, {}, true),
      rule("results.*.mad", {}, {}, true),
      rule("results.*.reps", kExact, B::info),
      rule("results.*.median", 0.15, B::auto_),
      rule("results.*.reference.median", 0.15, B::info),
      rule("results.*.ratio", 0.15, B::higher),
      rule("results.*.ratio_of_medians", 0.15, B::info),
      rule("results.*.meets_target", kExact, B::info),
  };
}

std::vector<ToleranceRule> load_tolerances(const std::string& path) {
  // Every TOML leaf is "<pattern>.<field>": the pattern may be one quoted key (["run.*"]) or a
  // dotted table path ([run.wall_s]); both flatten to the same key.
  std::vector<ToleranceRule> rules;
  std::map<std::string, std::size_t> index;
  std::vector<TomlEmptyTable> empty;
  const std::vector<TomlEntry> entries = read_toml_entries(path, &empty);
  // A pattern's table with no field would be a rule that changes nothing: a typo's likely sign.
  if (!empty.empty()) {  // the first in the file (the TOML tables come sorted by name)
    const auto& t = *std::min_element(empty.begin(), empty.end(), [](const auto& a, const auto& b) { return a.line < b.line; });
    throw InputError(at_line(path, t.line), "'" + t.key + "': a pattern with no field does nothing; give it abs, rel, "
                                            "better or ignore");
  }
  for (const TomlEntry& e : entries) {
    const std::string where = at_line(path, e.line);
    const auto dot = e.key.rfind('.');
    if (dot == 0) throw InputError(where, "the key pattern is empty ([\"\"] with field '" + e.key.substr(1) + "')");
    if (dot == std::string::npos)
      throw InputError(where, "'" + e.key + "': expected a table per key pattern, e.g. [\"latency_ms.*\"] rel = 0.05");
    const std::string pattern = e.key.substr(0, dot), field = e.key.substr(dot + 1);
    auto [it, fresh] = index.emplace(pattern, rules.size());
    if (fresh) {
      rules.push_back({});
      rules.back().pattern = pattern;
      rules.back().origin = where;
    }
    ToleranceRule& r = rules[it->second];
    if (field == "abs" || field == "rel") {
      double v;
      if (const auto* d = std::get_if<double>(&e.value)) v = *d;
      else if (const auto* i = std::get_if<std::int64_t>(&e.value)) v = static_cast<double>(*i);
      else throw InputError(where, "'" + pattern + "': field '" + field + "' must be a number");
      if (!std::isfinite(v) || v < 0)
        throw InputError(where, "'" + pattern + "': field '" + field + "' must be a finite number >= 0");
      (field == "abs" ? r.abs : r.rel) = v;
    } else if (field == "better") {
      const auto* s = std::get_if<std::string>(&e.value);
      const auto b = s ? parse_better(*s) : std::nullopt;
      if (!b) throw InputError(where, "'" + pattern + "': field 'better' must be \"lower\", \"higher\", \"both\", \"info\" or \"auto\"");
      r.better = b;
    } else if (field == "ignore") {
      const auto* b = std::get_if<bool>(&e.value);
      if (!b) throw InputError(where, "'" + pattern + "': field 'ignore' must be true or false");
      r.ignore = *b;
    } else {
      throw InputError(where, "'" + pattern + "': unknown field '" + field + "' (abs, rel, better, ignore)");
    }
  }
  return rules;
}

namespace {

// Specificity of a pattern: an exact key beats any wildcard; then more literal characters win.
std::pair<int, std::size_t> specificity(const std::string& p) {
  const auto stars = static_cast<std::size_t>(std::count(p.begin(), p.end(), '*'));
  return {stars == 0 ? 1 : 0, p.size() - stars};
}

template <class Get>
const ToleranceRule* best(const std::vector<ToleranceRule>& rules, const std::string& key, Get has) {
  const ToleranceRule* out = nullptr;
  std::pair<int, std::size_t> spec{-1, 0};
  for (const auto& r : rules) {
    if (!has(r) || !glob_match(r.pattern, key)) continue;
    const auto s = specificity(r.pattern);
    if (!out || s > spec) {
      out = &r;
      spec = s;
    }
  }
  return out;
}

template <class T, class Get>
T pick(const std::vector<ToleranceRule>& user, const std::vector<ToleranceRule>& defaults, const std::string& key,
       Get field, T fallback) {
  const auto has = [&](const ToleranceRule& r) { return field(r).has_value(); };
  if (const auto* r = best(user, key, has)) return *field(*r);
  if (const auto* r = best(defaults, key, has)) return *field(*r);
  return fallback;
}

}  // namespace

Tolerance resolve_tolerance(const std::vector<ToleranceRule>& user, const std::vector<ToleranceRule>& defaults,
                            const std::string& key, Better hint) {
  Tolerance t;
  t.abs = pick<double>(user, defaults, key, [](const ToleranceRule& r) { return r.abs; }, 0.0);
  t.rel = pick<double>(user, defaults, key, [](const ToleranceRule& r) { return r.rel; }, 0.0);
  t.better = pick<Better>(user, defaults, key, [](const ToleranceRule& r) { return r.better; }, Better::both);
  t.ignore = pick<bool>(user, defaults, key, [](const ToleranceRule& r) { return r.ignore; }, false);
  if (t.better == Better::auto_) t.better = hint == Better::auto_ ? Better::both : hint;
  return t;
}

// The shape a compared document may have (load_json_file says why): 16 levels, key paths of 1,024
// characters (the keys along the path), 200,000 leaf values.
constexpr int kMaxJsonDepth = 16;
constexpr std::size_t kMaxJsonKeyPath = 1024;
constexpr std::size_t kMaxJsonValues = 200000;

json load_json_file(const std::string& path) {
  const std::string text = read_regular_file(path, 256u << 20, "not a vtsim summary or benchmark JSON");
  // Bounds on the document's shape, checked while it is parsed: the walk below recurses once per
  // level and keeps a row (with its dotted key) per leaf, so unbounded depth overflows the stack
  // and a huge array or a long key path at every leaf exhausts memory. vtsim's own documents nest
  // 4 deep, with keys of ~30 characters and a few thousand leaves.
  std::vector<std::size_t> key_len;  // per depth, the length of the current key
  std::size_t values = 0;
  const auto bound = [&](int depth, json::parse_event_t event, json& parsed) {
    using E = json::parse_event_t;
    if ((event == E::object_start || event == E::array_start) && depth >= kMaxJsonDepth)
      throw InputError(path, fmt::format("nested deeper than {} levels: not a vtsim summary or benchmark JSON", kMaxJsonDepth));
    if (event == E::key) {
      key_len.resize(static_cast<std::size_t>(depth) + 1);
      key_len.back() = parsed.get_ref<const std::string&>().size() + 1;
      std::size_t sum = 0;
      for (const std::size_t n : key_len) sum += n;
      if (sum > kMaxJsonKeyPath)
        throw InputError(path, fmt::format("a key path longer than {} characters: not a vtsim summary or benchmark JSON",
                                           kMaxJsonKeyPath));
    }
    if (event == E::value && ++values > kMaxJsonValues)
      throw InputError(path, fmt::format("more than {} values: not a vtsim summary or benchmark JSON", kMaxJsonValues));
    return true;
  };
  try {
    return json::parse(text, bound);
  } catch (const json::parse_error& e) {
    // e.byte is the 1-based offset of the error; turn it into a line number.
    const std::size_t at = std::min<std::size_t>(e.byte > 0 ? e.byte - 1 : 0, text.size());
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n');
    throw InputError(at_line(path, static_cast<long long>(line)), "not valid JSON (" + std::string(e.what()) + ")");
  } catch (const json::exception& e) {  // e.g. a number beyond double's range (out_of_range.406)
    throw InputError(path, "not valid JSON (" + std::string(e.what()) + ")");
  }
}

DocKind detect_kind(const json& doc, const std::string& path) {
  if (!doc.is_object()) throw InputError(path, "not a vtsim summary or benchmark JSON (the top level is not an object)");
  if (doc.contains("schema")) {
    const json& schema = doc.at("schema");
    if (schema == kSummarySchema) {
      if (!doc.contains("trace")) throw InputError(path, "key 'trace' is missing (required in a replay summary)");
      return DocKind::summary;
    }
    if (!schema.is_string() || schema.get<std::string>() != "vtsim-bench/1")
      throw InputError(path, "key 'schema': " + schema.dump() + " is not a schema vtsim compare knows (\"vtsim-bench/1\", \"" +
                                 kSummarySchema + "\")");
    for (const char* k : {"benchmark", "results"})
      if (!doc.contains(k)) throw InputError(path, std::string("key '") + k + "' is missing (required by vtsim-bench/1)");
    if (!doc["benchmark"].is_string()) throw InputError(path, "key 'benchmark' must be a string");
    if (!doc["results"].is_array()) throw InputError(path, "key 'results' must be an array");
    return DocKind::bench;
  }
  if (doc.contains("vtsim_version")) {
    if (!doc.contains("trace")) throw InputError(path, "key 'trace' is missing (required in a replay summary)");
    return DocKind::summary;
  }
  throw InputError(path, "not a vtsim summary or benchmark JSON (neither a 'schema' nor a 'vtsim_version' key)");
}

std::size_t CompareReport::count(Verdict v) const {
  return static_cast<std::size_t>(std::count_if(rows.begin(), rows.end(), [v](const MetricDiff& d) { return d.verdict == v; }));
}

bool CompareReport::failed(bool strict) const {
  for (const auto& d : rows) {
    if (d.verdict == Verdict::worse || d.verdict == Verdict::changed) return true;
    if (strict && (d.verdict == Verdict::better || d.verdict == Verdict::added || d.verdict == Verdict::removed)) return true;
  }
  return false;
}

namespace {

// A benchmark's results array keyed by case name (then "@side", then "#n" if still ambiguous), so
// that adding or reordering cases does not shift every later comparison.
json key_bench_results(const json& doc, const std::string& path) {
  json out = doc;
  json by_name = json::object();
  const json& results = doc["results"];
  for (std::size_t i = 0; i < results.size(); ++i) {
    const json& r = results[i];
    const std::string at = "results[" + std::to_string(i) + "]";
    if (!r.is_object()) throw InputError(path, "key '" + at + "' must be an object");
    if (!r.contains("name") || !r["name"].is_string()) throw InputError(path, "key '" + at + ".name' is missing or not a string");
    std::string name = r["name"].get<std::string>();
    if (by_name.contains(name) && r.contains("side") && r["side"].is_string()) name += "@" + r["side"].get<std::string>();
    for (int n = 2; by_name.contains(name); ++n) name = r["name"].get<std::string>() + "#" + std::to_string(n);
    by_name[name] = r;
  }
  out["results"] = std::move(by_name);
  return out;
}

const char* type_name(const json& j) {
  if (j.is_object()) return "an object";
  if (j.is_array()) return "an array";
  if (j.is_string()) return "a string";
  if (j.is_boolean()) return "a boolean";
  if (j.is_number()) return "a number";
  return "null";
}

long double as_ld(const json& j) {
  if (j.is_boolean()) return j.get<bool>() ? 1.0L : 0.0L;
  if (j.is_number_unsigned()) return static_cast<long double>(j.get<std::uint64_t>());
  if (j.is_number_integer()) return static_cast<long double>(j.get<std::int64_t>());
  return static_cast<long double>(j.get<double>());
}

class Walker {
 public:
  Walker(const CompareOptions& opt, DocKind kind, bool real_clock, std::string base_path, std::string new_path,
         std::vector<MetricDiff>& rows)
      : opt_(opt), defaults_(default_tolerances(kind, opt.wall_clock, real_clock)), kind_(kind), base_path_(std::move(base_path)),
        new_path_(std::move(new_path)), rows_(rows) {}

  void walk(const json& b, const json& n, const std::string& key, Better hint) {
    hint = hint_for(b, key, hint);
    if (b.is_object() && n.is_object()) {
      for (const auto& [k, bv] : b.items()) {
        const std::string sub = join(key, k);
        if (const auto it = n.find(k); it != n.end()) walk(bv, *it, sub, hint);
        else missing(bv, sub, hint);
      }
      for (const auto& [k, nv] : n.items())
        if (!b.contains(k)) one_side(nv, join(key, k), hint, Verdict::added);
      return;
    }
    if (b.is_array() && n.is_array()) {
      leaf(key + "[]", json(b.size()), json(n.size()), hint);
      if (by_level(b) && by_level(n)) {
        // Per-level rows list only the levels that moved bytes: pair them by level, not position.
        for (const auto& e : b) {
          const json* other = find_level(n, e["level"]);
          if (other) walk(e, *other, level_key(key, e), hint);
          else one_side(e, level_key(key, e), hint, Verdict::removed);
        }
        for (const auto& e : n)
          if (!find_level(b, e["level"])) one_side(e, level_key(key, e), hint, Verdict::added);
        return;
      }
      const std::size_t common = std::min(b.size(), n.size());
      for (std::size_t i = 0; i < common; ++i) walk(b[i], n[i], index(key, i), hint);
      for (std::size_t i = common; i < b.size(); ++i) one_side(b[i], index(key, i), hint, Verdict::removed);
      for (std::size_t i = common; i < n.size(); ++i) one_side(n[i], index(key, i), hint, Verdict::added);
      return;
    }
    const bool scalar_b = !b.is_structured(), scalar_n = !n.is_structured();
    const bool compatible = scalar_b && scalar_n &&
                            (b.is_null() || n.is_null() || (b.is_string() == n.is_string() && b.is_boolean() == n.is_boolean()));
    if (!compatible) {
      if (tolerance(key, hint).ignore) return one_side(b, key, hint, Verdict::ignored);
      if (kind_ == DocKind::summary && is_identity_key(key)) return identity_row(b, n, key, hint);
      throw InputError(new_path_, fmt::format("key '{}' is {}, but {} in the base {}", key, type_name(n), type_name(b), base_path_));
    }
    leaf(key, b, n, hint);
  }

 private:
  static std::string join(const std::string& key, const std::string& k) { return key.empty() ? k : key + "." + k; }
  static std::string index(const std::string& key, std::size_t i) { return key + "[" + std::to_string(i) + "]"; }

  // An array of objects each with a distinct integer "level" (bandwidth.per_level).
  static bool by_level(const json& a) {
    if (a.empty()) return false;
    std::vector<std::int64_t> seen;
    for (const auto& e : a) {
      if (!e.is_object() || !e.contains("level") || !e["level"].is_number_integer()) return false;
      seen.push_back(e["level"].get<std::int64_t>());
    }
    std::sort(seen.begin(), seen.end());
    return std::adjacent_find(seen.begin(), seen.end()) == seen.end();
  }
  static const json* find_level(const json& a, const json& level) {
    for (const auto& e : a)
      if (e["level"] == level) return &e;
    return nullptr;
  }
  static std::string level_key(const std::string& key, const json& e) { return key + "[level=" + e["level"].dump() + "]"; }

  // A benchmark result's "better" field tells which way its medians go.
  Better hint_for(const json& b, const std::string& key, Better hint) const {
    if (kind_ == DocKind::bench && b.is_object() && key.rfind("results.", 0) == 0 && b.contains("better") &&
        b["better"].is_string()) {
      const auto p = parse_better(b["better"].get<std::string>());
      if (p == Better::lower || p == Better::higher) return *p;
    }
    return hint;
  }

  Tolerance tolerance(const std::string& key, Better hint) const { return resolve_tolerance(opt_.rules, defaults_, key, hint); }

  // A base object member absent from the new document: bad input unless every leaf is ignored
  // (or says what the run was: an older summary has no config).
  void missing(const json& b, const std::string& key, Better hint) {
    if (kind_ == DocKind::summary && is_identity_key(key)) return one_side(b, key, hint, Verdict::info);
    if (b.is_structured()) {
      bool any = false;
      const auto check = [&](const json&, const std::string& k) {
        if (!tolerance(k, hint).ignore) throw InputError(new_path_, fmt::format("key '{}' is missing (the base {} has it)", k, base_path_));
        any = true;
      };
      each_leaf(b, key, check);
      if (!any && !tolerance(key, hint).ignore)
        throw InputError(new_path_, fmt::format("key '{}' is missing (the base {} has it)", key, base_path_));
      one_side(b, key, hint, Verdict::ignored);
      return;
    }
    if (!tolerance(key, hint).ignore)
      throw InputError(new_path_, fmt::format("key '{}' is missing (the base {} has it)", key, base_path_));
    one_side(b, key, hint, Verdict::ignored);
  }

  template <class F>
  void each_leaf(const json& v, const std::string& key, F&& f) const {
    if (v.is_object()) {
      for (const auto& [k, x] : v.items()) each_leaf(x, join(key, k), f);
    } else if (v.is_array()) {
      f(json(v.size()), key + "[]");
      for (std::size_t i = 0; i < v.size(); ++i) each_leaf(v[i], index(key, i), f);
    } else {
      f(v, key);
    }
  }

  // Leaves present on one side only (added, removed, or ignored).
  void one_side(const json& v, const std::string& key, Better hint, Verdict verdict) {
    each_leaf(v, key, [&](const json& x, const std::string& k) {
      MetricDiff d;
      d.key = k;
      d.tol = tolerance(k, hint);
      (verdict == Verdict::added ? d.now : d.base) = x;
      d.verdict = d.tol.ignore ? Verdict::ignored : verdict;
      if (!d.tol.ignore && kind_ == DocKind::summary && is_identity_key(k)) d.verdict = Verdict::info;
      rows_.push_back(std::move(d));
    });
  }

  void leaf(const std::string& key, const json& b, const json& n, Better hint) {
    MetricDiff d;
    d.key = key;
    d.base = b;
    d.now = n;
    d.tol = tolerance(key, hint);
    // Floats get at least the float band (compare.h, kFloatRel): their last bits are not behaviour.
    if (!opt_.exact_floats && !d.tol.ignore && (b.is_number_float() || n.is_number_float())) {
      d.tol.abs = std::max(d.tol.abs, kFloatAbs);
      d.tol.rel = std::max(d.tol.rel, kFloatRel);
    }
    d.verdict = judge(b, n, d);
    rows_.push_back(std::move(d));
  }

  // An identity key whose two values have different shapes (a config value that became a table):
  // one info row with both sides as text.
  void identity_row(const json& b, const json& n, const std::string& key, Better hint) {
    MetricDiff d;
    d.key = key;
    d.base = b.is_structured() ? json(b.dump()) : b;
    d.now = n.is_structured() ? json(n.dump()) : n;
    d.tol = tolerance(key, hint);
    d.verdict = Verdict::info;
    rows_.push_back(std::move(d));
  }

  static Verdict judge(const json& b, const json& n, MetricDiff& d) {
    const Tolerance& t = d.tol;
    if (t.ignore) return Verdict::ignored;
    const Verdict any_change = t.better == Better::info ? Verdict::info : Verdict::changed;
    if (b == n) return Verdict::same;
    if (b.is_null() || n.is_null() || b.is_string()) return any_change;
    // Long double holds every uint64 byte count exactly (64-bit mantissa on x86-64).
    const long double lb = as_ld(b), ln = as_ld(n);
    if (lb == ln) return Verdict::same;  // 3 vs 3.0
    const long double delta = ln - lb;
    d.delta = static_cast<double>(delta);
    d.rel = lb != 0 ? static_cast<double>(delta / std::fabs(lb)) : 0.0;
    const long double allowed = std::max<long double>(t.abs, t.rel * std::fabs(lb));
    if (std::fabs(delta) <= allowed) return Verdict::within;
    switch (t.better) {
      case Better::lower: return delta > 0 ? Verdict::worse : Verdict::better;
      case Better::higher: return delta < 0 ? Verdict::worse : Verdict::better;
      case Better::info: return Verdict::info;
      default: return Verdict::changed;
    }
  }

  const CompareOptions& opt_;
  std::vector<ToleranceRule> defaults_;
  DocKind kind_;
  std::string base_path_, new_path_;
  std::vector<MetricDiff>& rows_;
};

}  // namespace

bool is_identity_key(const std::string& key) {
  return key == "schema" || key == "config" || key.rfind("config.", 0) == 0 || key == "trace.path" ||
         key == "trace.content_hash" || key == "trace.poses" || key == "trace.poses_duration_s";
}

namespace {

std::string compare_note_value(const json* v) {
  if (!v) return "(absent)";
  return v->is_string() ? v->get<std::string>() : v->dump();
}

// "path (hash, N poses, D s)" of a summary's trace, from what it has.
std::string compare_trace_identity(const json& t) {
  std::string out = t.contains("path") && t["path"].is_string() && !t["path"].get<std::string>().empty()
                        ? t["path"].get<std::string>()
                        : "'" + compare_note_value(t.contains("name") ? &t["name"] : nullptr) + "'";
  std::vector<std::string> parts;
  if (t.contains("content_hash") && t["content_hash"].is_string()) parts.push_back(t["content_hash"].get<std::string>());
  if (t.contains("poses")) parts.push_back(compare_note_value(&t["poses"]) + " poses");
  if (t.contains("poses_duration_s") && t["poses_duration_s"].is_number())
    parts.push_back(fmt::format("{:.6g} s", t["poses_duration_s"].get<double>()));
  for (std::size_t i = 0; i < parts.size(); ++i) out += (i ? ", " : " (") + parts[i] + (i + 1 == parts.size() ? ")" : "");
  return out;
}

// The notes of a summary comparison (CompareReport::notes).
std::vector<std::string> summary_notes(const json& base, const json& now, const CompareOptions& opt) {
  std::vector<std::string> notes;
  if (base.contains("schema") != now.contains("schema"))
    notes.push_back(fmt::format("the {} summary has no schema (written before {}): it lacks the run's identity", 
                                base.contains("schema") ? "new" : "base", kSummarySchema));
  // Configs: every key, defaults included, so any difference is a real one.
  const json* bc = base.contains("config") && base["config"].is_object() ? &base["config"] : nullptr;
  const json* nc = now.contains("config") && now["config"].is_object() ? &now["config"] : nullptr;
  if (bc && nc) {
    std::vector<std::string> diffs;
    std::map<std::string, int> keys;
    for (const auto& [k, v] : bc->items()) keys[k] |= 1;
    for (const auto& [k, v] : nc->items()) keys[k] |= 2;
    for (const auto& [k, sides] : keys) {
      const json* b = sides & 1 ? &(*bc)[k] : nullptr;
      const json* n = sides & 2 ? &(*nc)[k] : nullptr;
      if (b && n && *b == *n) continue;
      diffs.push_back(fmt::format("{} ({} -> {})", k, compare_note_value(b), compare_note_value(n)));
    }
    constexpr std::size_t kShown = 12;  // a sweep-sized difference: the first ones and a count
    if (!diffs.empty()) {
      std::string list;
      for (std::size_t i = 0; i < diffs.size() && i < kShown; ++i) list += (i ? ", " : "") + diffs[i];
      if (diffs.size() > kShown) list += fmt::format(" and {} more", diffs.size() - kShown);
      notes.push_back(fmt::format("the two runs' configs differ in {} key{}: {}", diffs.size(), diffs.size() == 1 ? "" : "s", list));
    }
  } else if (bc || nc) {
    notes.push_back(fmt::format("the {} summary records no config: whether the configs differ is unknown", bc ? "new" : "base"));
  }
  // Traces: by content when both have a hash, else by what both record.
  const json& bt = base["trace"];
  const json& nt = now["trace"];
  if (bt.is_object() && nt.is_object()) {
    const auto field = [](const json& t, const char* k) { return t.contains(k) ? t[k] : json(); };
    const json bh = field(bt, "content_hash"), nh = field(nt, "content_hash");
    bool differ;
    if (bh.is_string() && nh.is_string()) differ = bh != nh;
    else differ = field(bt, "name") != field(nt, "name") || field(bt, "poses") != field(nt, "poses") ||
                  field(bt, "poses_duration_s") != field(nt, "poses_duration_s");
    if (differ)
      notes.push_back(fmt::format("the two runs' traces differ: base {}, new {}", compare_trace_identity(bt), compare_trace_identity(nt)));
  }
  const auto real = [](const json& d) { return d.contains("clock") && d["clock"] == "real"; };
  if (real(base) || real(now))
    notes.push_back("a real-clock run: its latency, pop-in, bandwidth and counts were measured in wall-clock time and move "
                    "between runs; compared within 25% (a --tolerances file sets other bands; docs/compare.md)");
  if (!opt.wall_clock && (base.contains("run") || base.contains("real_clock")))
    notes.push_back("wall-clock sections (run.*, real_clock.*) not compared; --wall-clock compares them within 25%");
  return notes;
}

}  // namespace

namespace {

// A latency is measured over the requests served: when fewer of them were (the served fraction
// fell) or more tiles were never requested (throttled), a lower latency is not an improvement
// (HDD's p95 below NVMe's while blur doubled). Such a row is "changed" (judged both ways), with a note.
void not_better_when_fewer_served(const json& base, const json& now, CompareReport& r) {
  const auto number = [](const json& d, const char* a, const char* b) -> std::optional<long double> {
    if (!d.is_object() || !d.contains(a) || !d[a].is_object() || !d[a].contains(b) || !d[a][b].is_number()) return std::nullopt;
    return as_ld(d[a][b]);
  };
  std::vector<std::string> why;
  const auto fb = number(base, "latency_ms", "served_fraction"), fn = number(now, "latency_ms", "served_fraction");
  if (fb && fn && *fn < *fb - std::max<long double>(kFloatAbs, kFloatRel * std::fabs(*fb)))
    why.push_back(fmt::format("the served fraction fell ({:.6g} -> {:.6g})", static_cast<double>(*fb), static_cast<double>(*fn)));
  const auto tb = number(base, "throttle", "requests_throttled"), tn = number(now, "throttle", "requests_throttled");
  if (tb && tn && *tn > *tb)
    why.push_back(fmt::format("more tiles were throttled, never requested ({:.0f} -> {:.0f})", static_cast<double>(*tb),
                              static_cast<double>(*tn)));
  if (why.empty()) return;
  std::size_t n = 0;
  for (MetricDiff& d : r.rows)
    if (d.verdict == Verdict::better && is_served_latency_key(d.key)) d.verdict = Verdict::changed, ++n;
  if (n == 0) return;
  std::string text = why[0];
  for (std::size_t i = 1; i < why.size(); ++i) text += " and " + why[i];
  r.notes.push_back(fmt::format("{} latency value{} lower but not better: {} (a latency over fewer of the wanted "
                                "tiles, docs/metrics.md)",
                                n, n == 1 ? " is" : "s are", text));
}

}  // namespace

CompareReport compare_documents(const json& base, const std::string& base_path, const json& now, const std::string& new_path,
                                const CompareOptions& opt) {
  CompareReport r;
  r.base_path = base_path;
  r.new_path = new_path;
  r.kind = detect_kind(base, base_path);
  const DocKind nk = detect_kind(now, new_path);
  if (nk != r.kind)
    throw InputError(new_path, fmt::format("is a {} JSON, but the base {} is a {} JSON", to_string(nk), base_path, to_string(r.kind)));
  const auto is_real = [](const json& d) { return d.is_object() && d.contains("clock") && d["clock"] == "real"; };
  Walker w(opt, r.kind, is_real(base) || is_real(now), base_path, new_path, r.rows);
  if (r.kind == DocKind::bench) {
    if (base["benchmark"] != now["benchmark"])
      throw InputError(new_path, fmt::format("key 'benchmark': {} is not the base's benchmark {} ({})", now["benchmark"].dump(),
                                             base["benchmark"].dump(), base_path));
    w.walk(key_bench_results(base, base_path), key_bench_results(now, new_path), "", Better::auto_);
  } else {
    w.walk(base, now, "", Better::auto_);
    r.notes = summary_notes(base, now, opt);
    not_better_when_fewer_served(base, now, r);
  }
  return r;
}

namespace {

std::string scalar_text(const json& v) {
  if (v.is_null()) return "-";
  if (v.is_string()) return v.get<std::string>();
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  if (v.is_number_integer()) return v.dump();
  return fmt::format("{:.6g}", v.get<double>());
}

std::string change_text(const MetricDiff& d) {
  if (d.verdict == Verdict::same || d.verdict == Verdict::ignored || d.verdict == Verdict::added ||
      d.verdict == Verdict::removed)
    return "";
  if (d.base.is_null() || d.now.is_null() || d.base.is_string()) return "changed";
  std::string s = fmt::format("{:+.4g}", d.delta);
  if (d.base.is_number() && as_ld(d.base) != 0) s += fmt::format(" ({:+.2f}%)", 100.0 * d.rel);
  return s;
}

std::string tolerance_text(const Tolerance& t) {
  if (t.ignore) return "ignored";
  std::string band;
  if (t.abs == 0 && t.rel == 0) band = "exact";
  else if (t.abs == 0) band = fmt::format("±{:g}%", 100.0 * t.rel);
  else if (t.rel == 0) band = fmt::format("±{:g}", t.abs);
  else band = fmt::format("±max({:g}, {:g}%)", t.abs, 100.0 * t.rel);
  return band + ", " + to_string(t.better);
}

std::string result_word(const CompareReport& r, bool strict) { return r.failed(strict) ? "REGRESSION" : "OK"; }

}  // namespace

std::string format_report(const CompareReport& r, bool all, bool strict) {
  std::vector<std::array<std::string, 6>> table;
  table.push_back({"key", "base", "new", "change", "tolerance", "verdict"});
  for (const auto& d : r.rows) {
    if (!all && (d.verdict == Verdict::same || d.verdict == Verdict::ignored)) continue;
    table.push_back({d.key, scalar_text(d.base), scalar_text(d.now), change_text(d), tolerance_text(d.tol), to_string(d.verdict)});
  }
  std::string out = fmt::format("vtsim compare ({}): base {} -> new {}\n", to_string(r.kind), r.base_path, r.new_path);
  if (table.size() > 1) {
    std::array<std::size_t, 6> w{};
    // Column widths in characters; '±' is two bytes in UTF-8 but one column.
    const auto width = [](const std::string& s) {
      return static_cast<std::size_t>(std::count_if(s.begin(), s.end(), [](char c) { return (c & 0xC0) != 0x80; }));
    };
    for (const auto& row : table)
      for (std::size_t i = 0; i < 6; ++i) w[i] = std::max(w[i], width(row[i]));
    for (const auto& row : table) {
      std::string line = " ";
      for (std::size_t i = 0; i < 6; ++i) {
        const std::size_t pad = w[i] - width(row[i]);
        const bool right = i >= 1 && i <= 2;  // numbers right-aligned
        line.push_back(' ');
        if (right) line.append(pad, ' ');
        line.append(row[i]);
        if (!right && i < 5) line.append(pad, ' ');
      }
      line.push_back('\n');
      out.append(line);
    }
  } else {
    out += "  no differences\n";
  }
  for (const auto& n : r.notes) out += "note: " + n + "\n";
  out += fmt::format("{}: {} worse, {} changed, {} better, {} within tolerance, {} info, {} added, {} removed, {} same, "
                     "{} ignored ({} keys{})\n",
                     result_word(r, strict), r.count(Verdict::worse), r.count(Verdict::changed), r.count(Verdict::better),
                     r.count(Verdict::within), r.count(Verdict::info), r.count(Verdict::added), r.count(Verdict::removed),
                     r.count(Verdict::same), r.count(Verdict::ignored), r.rows.size(), strict ? ", strict" : "");
  return out;
}

json report_json(const CompareReport& r, bool all, bool strict) {
  json rows = json::array();
  for (const auto& d : r.rows) {
    if (!all && (d.verdict == Verdict::same || d.verdict == Verdict::ignored)) continue;
    rows.push_back({{"key", d.key},
                    {"base", d.base},
                    {"new", d.now},
                    {"delta", d.delta},
                    {"rel", d.rel},
                    {"tolerance", {{"abs", d.tol.abs}, {"rel", d.tol.rel}, {"better", to_string(d.tol.better)}, {"ignore", d.tol.ignore}}},
                    {"verdict", to_string(d.verdict)}});
  }
  json counts = json::object();
  for (Verdict v : {Verdict::same, Verdict::within, Verdict::better, Verdict::worse, Verdict::changed, Verdict::info,
                    Verdict::added, Verdict::removed, Verdict::ignored}) {
    std::string name = to_string(v);
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    counts[name] = r.count(v);
  }
  return {{"base", r.base_path}, {"new", r.new_path}, {"kind", to_string(r.kind)}, {"strict", strict},
          {"result", r.failed(strict) ? "regression" : "ok"}, {"counts", counts}, {"notes", r.notes}, {"rows", rows}};
}

}  // namespace vtsim
