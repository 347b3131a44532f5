#include "sim/sweep/sweep_spec.h"

#include "sim/trace/feedback_trace.h"

#include <fmt/format.h>
#include <glob.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <utility>
#include <vector>
#include <toml++/toml.h>

#include "core/error.h"
#include "core/input_file.h"
#include "core/text.h"
#include "core/toml_text.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_import.h"

namespace vtsim {

namespace {

namespace fs = std::filesystem;

constexpr std::uint64_t kMaxSpecBytes = 4u << 20;
// A grid larger than this is almost certainly a typo (a 1e6-point sweep is weeks of CPU).
constexpr std::size_t kMaxPoints = 100000;

using KeyValues = std::vector<std::pair<std::string, ConfigValue>>;

long long line_of(const toml::node& n) { return static_cast<long long>(n.source().begin.line); }

// A scalar as a config value; InputError at spec:line for anything else.
ConfigValue scalar(const toml::node& n, const std::string& where, const std::string& key) {
  if (const auto* i = n.as_integer()) return static_cast<std::int64_t>(i->get());
  if (const auto* d = n.as_floating_point()) return d->get();
  if (const auto* b = n.as_boolean()) return b->get();
  if (const auto* s = n.as_string()) {
    if (s->get().find('\0') != std::string::npos) throw InputError(where, "key '" + key + "': a string with a NUL character");
    return s->get();
  }
  throw InputError(where, "key '" + key + "': expected a number, boolean or string");
}

// Nested tables flattened into dotted keys, in the file's order (toml++ keeps keys sorted).
void flatten(const toml::table& t, const std::string& prefix, std::vector<std::pair<std::string, const toml::node*>>& out) {
  for (const auto& [k, node] : t) {
    const std::string key = prefix.empty() ? std::string(k.str()) : prefix + "." + std::string(k.str());
    if (const auto* sub = node.as_table()) flatten(*sub, key, out);
    else out.emplace_back(key, &node);
  }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    const auto la = a.second->source().begin, lb = b.second->source().begin;
    return la.line != lb.line ? la.line < lb.line : la.column < lb.column;
  });
}

std::vector<std::string> strings(const toml::node& n, const std::string& path, const std::string& key) {
  const auto* arr = n.as_array();
  std::vector<std::string> out;
  if (const auto* s = n.as_string()) return {s->get()};
  if (!arr) throw InputError(at_line(path, line_of(n)), "key '" + key + "': expected a list of strings");
  for (const auto& e : *arr) {
    const auto* s = e.as_string();
    if (!s) throw InputError(at_line(path, line_of(e)), "key '" + key + "': expected a list of strings");
    out.push_back(s->get());
  }
  return out;
}

fs::path resolve(const fs::path& dir, const std::string& p) { return fs::path(p).is_absolute() ? fs::path(p) : dir / p; }

std::vector<std::string> expand_glob(const std::string& pattern, const std::string& where) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), GLOB_ERR, nullptr, &g);
  std::vector<std::string> out;
  for (std::size_t i = 0; rc == 0 && i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
  globfree(&g);
  if (out.empty()) throw InputError(where, "traces: '" + pattern + "' matches no file");
  std::sort(out.begin(), out.end());
  return out;
}

void check_key(const std::string& key, const std::string& where) {
  if (!replay_config_table().find(key)) {
    ReplayConfig probe;
    replay_config_table().set(probe, key, ConfigValue{std::int64_t{0}}, where);  // throws: unknown key, did-you-mean
  }
}

// Applies a point's values to a copy of the base; InputError naming the spec line and key.
ReplayConfig make_point(const ReplayConfig& base, const KeyValues& values, const std::vector<long long>& lines,
                        const std::string& path) {
  ReplayConfig c = base;
  for (std::size_t i = 0; i < values.size(); ++i)
    replay_config_table().set(c, values[i].first, values[i].second, at_line(path, lines[i]));
  return c;
}

}  // namespace

const std::vector<std::string>& default_sweep_metrics() {
  static const std::vector<std::string> m = {
      "popin.blurry_fraction_mean", "popin.blurry_fraction_p99", "popin.time_to_sharp_s.mean",
      "popin.time_to_sharp_s.max",  "popin.visible_pops",        "latency_ms.p50",
      "latency_ms.p99",             "bandwidth.disk_read_MBps",  "bandwidth.upload_MBps",
      "cache.ram_hit_ratio",        "throttle.frames_throttled"};
  return m;
}

namespace {

// The spec's [tune] table (spec.tune; InputError naming its line otherwise).
void spec_tune(const toml::node& node, const std::string& path, SweepSpec& spec) {
  const auto* t = node.as_table();
  if (!t) throw InputError(at_line(path, line_of(node)), "key 'tune': expected a [tune] table");
  spec.tune.line = line_of(node);
  for (const auto& [tk, tn] : *t) {
    const std::string tkey(tk.str());
    const std::string tw = at_line(path, line_of(tn));
    if (tkey == "constraints") {
      for (const std::string& c : strings(tn, path, "tune.constraints")) {
        spec.tune.constraints.push_back(parse_tune_constraint(c, tw));
        spec.tune.constraints.back().line = line_of(tn);
      }
    } else if (tkey == "costs") {
      spec.tune.costs = strings(tn, path, "tune.costs");
    } else {
      throw InputError(tw, "unknown key 'tune." + tkey + "' (keys: constraints, costs)");
    }
  }
}

// The spec's top-level keys, in the file's order, into `spec`; the [grid] and [[configs]] it
// holds, and the lines of `config` and `set`, for the steps after.
struct SpecTop {
  const toml::table* grid = nullptr;
  const toml::array* configs = nullptr;
  long long config_line = 0, set_line = 0;
};

SpecTop spec_top_keys(const toml::table& tbl, const std::string& path, SweepSpec& spec) {
  const fs::path dir = fs::path(path).parent_path();
  std::vector<std::pair<std::string, const toml::node*>> top;
  for (const auto& [k, node] : tbl) top.emplace_back(std::string(k.str()), &node);
  std::stable_sort(top.begin(), top.end(), [](const auto& a, const auto& b) {  // the file's order
    return line_of(*a.second) < line_of(*b.second);
  });
  SpecTop r;
  const toml::table*& grid = r.grid;
  const toml::array*& configs = r.configs;
  long long& config_line = r.config_line;
  long long& set_line = r.set_line;
  for (const auto& [key, node] : top) {
    const std::string where = at_line(path, line_of(*node));
    if (key == "name") {
      if (!node->as_string()) throw InputError(where, "key 'name': expected a string");
      spec.name = node->as_string()->get();
    } else if (key == "config") {
      if (!node->as_string()) throw InputError(where, "key 'config': expected a file name");
      spec.base_config = resolve(dir, node->as_string()->get()).string();
      config_line = line_of(*node);
    } else if (key == "set") {
      spec.base_sets = strings(*node, path, key);
      set_line = line_of(*node);
    } else if (key == "traces") {
      for (const std::string& t : strings(*node, path, key)) {
        const std::string p = resolve(dir, t).string();
        if (t.find_first_of("*?[") != std::string::npos)
          for (std::string& f : expand_glob(p, where)) spec.traces.push_back({std::move(f), false, line_of(*node)});
        else
          spec.traces.push_back({p, false, line_of(*node)});
      }
    } else if (key == "generate") {
      for (const std::string& g : strings(*node, path, key)) {
        parse_gen_line(g, where + ": generate");  // refused now, not when the trace is needed
        spec.traces.push_back({g, true, line_of(*node)});
      }
    } else if (key == "metrics") {
      spec.metrics = strings(*node, path, key);
      spec.metrics_line = line_of(*node);
      for (std::size_t i = 0; i < spec.metrics.size(); ++i) {
        if (spec.metrics[i].empty()) throw InputError(where, "metrics: an empty metric name");
        for (std::size_t j = 0; j < i; ++j)
          if (spec.metrics[j] == spec.metrics[i]) throw InputError(where, "metrics: '" + spec.metrics[i] + "' twice");
      }
    } else if (key == "grid") {
      grid = node->as_table();
      if (!grid) throw InputError(where, "key 'grid': expected a table of key = [values]");
    } else if (key == "tune") {
      spec.tune.present = true;
      spec_tune(*node, path, spec);
    } else if (key == "allow_repairs") {
      if (!node->as_boolean()) throw InputError(where, "key 'allow_repairs': expected true or false");
      spec.allow_repairs = node->as_boolean()->get();
    } else if (key == "blur_bound") {
      const auto* d = node->as_floating_point();
      const auto* i = node->as_integer();
      const double v = d ? d->get() : i ? static_cast<double>(i->get()) : -1.0;
      if (!(v >= 0.0 && v <= 1.0)) throw InputError(where, "key 'blur_bound': expected a number from 0 to 1 (a blurry fraction)");
      spec.blur_bound = v;
    } else if (key == "configs") {
      configs = node->as_array();
      if (!configs) throw InputError(where, "key 'configs': expected [[configs]] tables");
    } else {
      throw InputError(where, "unknown spec key '" + key +
                                  "' (keys: name, config, set, traces, generate, allow_repairs, metrics, blur_bound, [grid], [[configs]], [tune])");
    }
  }
  return r;
}

// The base config, as `vtsim replay --config F --set S...` builds it (validated at each point).
// Errors inside the base config name its file and line; the spec's line says where it was named.
ReplayConfig spec_base_config(const std::string& path, const SpecTop& top, SweepSpec& spec) {
  const long long config_line = top.config_line, set_line = top.set_line;
  ReplayConfig base;
  const auto& table = replay_config_table();
  if (!spec.base_config.empty()) {
    try {
      load_toml_file(table, base, spec.base_config);
    } catch (const InputError& e) {
      throw InputError(at_line(path, config_line), std::string("key 'config': ") + e.what());
    }
  }
  for (const std::string& s : spec.base_sets) {
    try {
      apply_set(table, base, s);
    } catch (const InputError& e) {
      throw InputError(at_line(path, set_line), "key 'set': '" + s + "': " + e.what());
    }
  }
  spec.base_dump = table.dump(base);
  return base;
}

// The [grid] axes into spec.grid; each axis's values, as the points take them.
std::vector<std::vector<ConfigValue>> spec_axes(const toml::table* grid, const std::string& path, SweepSpec& spec) {
  std::vector<std::vector<ConfigValue>> grid_values;
  if (grid) {
    std::vector<std::pair<std::string, const toml::node*>> keys;
    flatten(*grid, "", keys);
    for (const auto& [key, node] : keys) {
      const std::string where = at_line(path, line_of(*node));
      check_key(key, where);
      SweepAxis axis{key, {}, line_of(*node)};
      const auto* arr = node->as_array();
      if (!arr) throw InputError(where, "grid key '" + key + "': expected a list of values, e.g. [4, 8, 16]");
      if (arr->empty()) throw InputError(where, "grid key '" + key + "': an empty axis (no config would run)");
      for (const SweepAxis& a : spec.grid)  // "vt.pool_pages" and [grid.vt] pool_pages are one key
        if (a.key == key) throw InputError(where, fmt::format("grid key '{}': an axis already (line {})", key, a.line));
      grid_values.emplace_back();
      for (const auto& e : *arr) {
        grid_values.back().push_back(scalar(e, where, key));
        axis.values.push_back(config_value_to_string(grid_values.back().back()));
        // Two equal values would run the same configs twice and make two points of one (tune's
        // order of cost would have a tie it cannot rank).
        for (std::size_t v = 0; v + 1 < axis.values.size(); ++v)
          if (axis.values[v] == axis.values.back())
            throw InputError(where, "grid key '" + key + "': the value " + axis.values.back() + " twice");
      }
      spec.grid.push_back(std::move(axis));
    }
  }
  return grid_values;
}

// The [[configs]] tables into spec.configs; each one's values and their lines, for the points.
void spec_explicit_configs(const toml::array* configs, const std::string& path, SweepSpec& spec,
                           std::vector<KeyValues>& explicit_sets, std::vector<std::vector<long long>>& explicit_lines) {
  if (configs) {
    for (const auto& e : *configs) {
      const auto* t = e.as_table();
      const std::string where = at_line(path, line_of(e));
      if (!t) throw InputError(where, "[[configs]]: expected a table of key = value");
      std::vector<std::pair<std::string, const toml::node*>> keys;
      flatten(*t, "", keys);
      KeyValues kv;
      std::vector<long long> lines;
      std::vector<std::pair<std::string, std::string>> texts;
      for (const auto& [key, node] : keys) {
        const std::string w = at_line(path, line_of(*node));
        check_key(key, w);
        for (const auto& [k, v] : kv)
          if (k == key) throw InputError(w, "[[configs]]: key '" + key + "' twice in one table");
        // A point takes the grid's value, so a key in both would be silently overridden.
        for (const SweepAxis& a : spec.grid)
          if (a.key == key)
            throw InputError(w, fmt::format("[[configs]]: key '{}' is also a [grid] axis (line {}); give it in one place", key, a.line));
        kv.emplace_back(key, scalar(*node, w, key));
        lines.push_back(line_of(*node));
        texts.emplace_back(key, config_value_to_string(kv.back().second));
      }
      explicit_sets.push_back(std::move(kv));
      explicit_lines.push_back(std::move(lines));
      spec.configs.push_back(std::move(texts));
    }
  }
}

// The points: explicit configs × grid (the grid's first axis slowest, its last fastest), each
// made from the base and validated.
void spec_points(const std::string& path, const ReplayConfig& base, const std::vector<std::vector<ConfigValue>>& grid_values,
                 const std::vector<KeyValues>& explicit_sets, const std::vector<std::vector<long long>>& explicit_lines,
                 SweepSpec& spec) {
  std::size_t grid_points = 1;
  for (const SweepAxis& a : spec.grid) {
    grid_points *= a.values.size();
    if (grid_points > kMaxPoints) throw InputError(at_line(path, a.line), fmt::format("the grid has over {} points", kMaxPoints));
  }
  if (grid_points * explicit_sets.size() > kMaxPoints)
    throw InputError(path, fmt::format("{} points (over {})", grid_points * explicit_sets.size(), kMaxPoints));
  for (std::size_t x = 0; x < explicit_sets.size(); ++x) {
    for (std::size_t g = 0; g < grid_points; ++g) {
      KeyValues kv = explicit_sets[x];
      std::vector<long long> lines = explicit_lines[x];
      std::size_t rest = g;
      std::vector<std::size_t> idx(spec.grid.size());
      for (std::size_t a = spec.grid.size(); a-- > 0;) {
        idx[a] = rest % spec.grid[a].values.size();
        rest /= spec.grid[a].values.size();
      }
      for (std::size_t a = 0; a < spec.grid.size(); ++a) {
        kv.emplace_back(spec.grid[a].key, grid_values[a][idx[a]]);
        lines.push_back(spec.grid[a].line);
      }
      SweepPoint p;
      p.index = static_cast<int>(spec.points.size());
      p.cfg = make_point(base, kv, lines, path);
      try {
        validate(p.cfg);
      } catch (const InputError& e) {
        std::string vals;
        for (const auto& [k, v] : kv) vals += (vals.empty() ? "" : ", ") + k + " = " + config_value_to_string(v);
        throw InputError(path, fmt::format("config point {} ({}): {}", p.index, vals.empty() ? "the base" : vals, e.what()));
      }
      for (const auto& [k, v] : kv) {
        p.values.emplace_back(k, config_value_to_string(v));
        if (std::find(spec.axis_keys.begin(), spec.axis_keys.end(), k) == spec.axis_keys.end()) spec.axis_keys.push_back(k);
      }
      spec.points.push_back(std::move(p));
    }
  }
}

}  // namespace

SweepSpec load_sweep_spec(const std::string& path) {
  const std::string text = read_regular_file(path, kMaxSpecBytes, "not a sweep spec");
  const toml::table tbl = parse_toml_text(text, path);
  SweepSpec spec;
  spec.path = path;
  const SpecTop top = spec_top_keys(tbl, path, spec);
  if (spec.traces.empty()) throw InputError(path, "no traces: give traces = [\"file.csv\", \"dir/*.csv\"] or generate = [\"walk duration_s=60\"]");
  if (spec.metrics.empty()) spec.metrics = default_sweep_metrics();

  const ReplayConfig base = spec_base_config(path, top, spec);

  const std::vector<std::vector<ConfigValue>> grid_values = spec_axes(top.grid, path, spec);
  std::vector<KeyValues> explicit_sets;
  std::vector<std::vector<long long>> explicit_lines;
  spec_explicit_configs(top.configs, path, spec, explicit_sets, explicit_lines);
  if (explicit_sets.empty()) explicit_sets.emplace_back(), explicit_lines.emplace_back();
  for (const std::string& c : spec.tune.costs)
    if (std::none_of(spec.grid.begin(), spec.grid.end(), [&](const SweepAxis& a) { return a.key == c; }))
      throw InputError(at_line(path, spec.tune.line), "tune.costs: '" + c + "' is not a [grid] axis");
  if (spec.tune.present && spec.tune.costs.empty())
    for (const SweepAxis& a : spec.grid) spec.tune.costs.push_back(a.key);
  // The constraints' metrics are reported too.
  for (const TuneConstraint& c : spec.tune.constraints)
    if (std::find(spec.metrics.begin(), spec.metrics.end(), c.metric) == spec.metrics.end()) spec.metrics.push_back(c.metric);

  spec_points(path, base, grid_values, explicit_sets, explicit_lines, spec);
  return spec;
}

TuneConstraint parse_tune_constraint(const std::string& text, const std::string& where) {
  TuneConstraint c;
  c.text = text;
  std::size_t op = text.find("<=");
  c.at_most = op != std::string::npos;
  if (op == std::string::npos) op = text.find(">=");
  const auto trim = [](std::string s) {
    const std::size_t b = s.find_first_not_of(" \t"), e = s.find_last_not_of(" \t");
    return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
  };
  if (op != std::string::npos) {
    c.metric = trim(text.substr(0, op));
    const std::string v = trim(text.substr(op + 2));
    if (!c.metric.empty() && text::parse_whole(v, c.bound) && std::isfinite(c.bound)) return c;
  }
  throw InputError(where, "tune constraint '" + text + "' is not 'metric <= number' or 'metric >= number' "
                          "(e.g. \"popin.blurry_fraction_p99 <= 0.02\")");
}

Trace load_sweep_trace(const SweepTraceSource& src, std::vector<std::string>* warnings, bool allow_repairs) {
  if (src.generated) return generate_trace(parse_gen_line(src.text, "generate"));
  if (is_feedback_trace(src.text)) return feedback_trace_poses(src.text);  // replayed by run_lockstep (docs/feedback.md)
  TraceLoadReport rep;
  TraceReadOptions read;
  read.allow_repairs = allow_repairs;
  Trace t = load_any_trace(src.text, read, &rep);
  if (warnings)
    for (std::string& w : repair_warnings(rep.repairs, rep.poses + rep.repairs.dropped(), src.text))
      warnings->push_back(std::move(w));
  return t;
}

}  // namespace vtsim
