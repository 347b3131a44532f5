// vtsim mrc: the LRU miss-ratio curve of an access sequence, exact (Mattson 1970) or sampled
// (SHARDS), with its knee (docs/cache.md, "Miss-ratio curves").
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "cache/policy/access_io.h"
#include "cache/policy/mrc.h"
#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/trace_load.h"
#include "cli/format.h"
#include "core/error.h"
#include "sim/report/mrc_chart.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "sim/run/systems.h"
#include "sim/trace/trace_import.h"
#include "cache/policy/belady.h"

namespace vtsim::cli {

namespace {

struct MrcArgs {
  std::string accesses;
  // Or a replay whose accesses are recorded (sim/run/replay.h, record_accesses):
  std::string trace, system, level, record;
  std::vector<std::string> configs;
  std::vector<std::string> sets;
  bool opt = false, allow_repairs = false;
  std::string unit;  // empty: pages for an access file; a replay's level sets its own
  std::optional<double> shards;  // absent: exact
  int sizes = 17;
  std::string json_file, csv, svg;
  bool json = false;
};

// Most sizes a curve is printed or written at: a few hundred kB of JSON.
constexpr int kMrcMaxSizes = 10000;

void mrc_write_text(const std::string& path, const std::string& text) { write_output(path, text); }

std::string mrc_size_text(std::uint64_t c, MrcUnit unit) {
  return unit == MrcUnit::kBytes ? human_bytes(static_cast<double>(c)) : fmt::format("{} pages", c);
}

nlohmann::json mrc_json(const MissRatioCurve& c, const std::string& source) {
  nlohmann::json j;
  j["source"] = source;
  j["unit"] = mrc_unit_name(c.unit);
  j["method"] = c.shards_rate > 0 ? "shards_adj" : "exact";
  j["shards_rate"] = c.shards_rate;
  j["accesses"] = c.accesses;
  j["keys"] = c.keys;
  j["footprint"] = c.footprint;
  j["max_size"] = c.max_size;
  j["size_changes"] = c.size_changes;
  nlohmann::json pts = nlohmann::json::array();
  for (std::size_t i = 0; i < c.capacity.size(); ++i) pts.push_back({{"capacity", c.capacity[i]}, {"miss_ratio", c.miss_ratio[i]}});
  j["curve"] = pts;
  j["knee"] = c.knee.found ? nlohmann::json{{"capacity", c.knee.capacity}, {"miss_ratio", c.knee.miss_ratio}}
                           : nlohmann::json(nullptr);
  return j;
}

// Prints the curve and writes the outputs asked for. `source` names where the accesses came from
// (a file; a replay's level when the recorder is wired in).
void report_mrc(const MissRatioCurve& c, const std::string& source, const MrcArgs& a, const std::vector<std::uint64_t>& opt) {
  const auto opt_ratio = [&](std::size_t i) {
    return c.accesses ? static_cast<double>(opt[i]) / static_cast<double>(c.accesses) : 0.0;
  };
  const char* unit = mrc_unit_name(c.unit);
  if (!a.json) {  // --json: the JSON below instead
    fmt::print("{}: {} accesses, {} keys, footprint {}\n", source, c.accesses, c.keys, mrc_size_text(c.footprint, c.unit));
    if (c.shards_rate > 0)
      fmt::print("LRU miss-ratio curve, SHARDS_adj at rate {:g} (Waldspurger et al. 2015; estimated)\n", c.shards_rate);
    else
      fmt::print("LRU miss-ratio curve, exact (Mattson et al. 1970 stack distances)\n");
    fmt::print("  {:>16}  {:>10}{}\n", fmt::format("size ({})", unit), "miss ratio", opt.empty() ? "" : "  Belady ratio");
    for (std::size_t i = 0; i < c.capacity.size(); ++i)
      fmt::print("  {:>16}  {:>10.4f}{}{}{}\n", c.capacity[i], c.miss_ratio[i],
                 opt.empty() ? std::string() : fmt::format("  {:>12.4f}", opt_ratio(i)),
                 c.unit == MrcUnit::kBytes ? "  " + human_bytes(static_cast<double>(c.capacity[i])) : "",
                 c.knee.found && c.knee.index == i ? "  <- nearest the knee" : "");
    if (c.knee.found)
      fmt::print("knee (Kneedle): {} ({} {}), miss ratio {:.4f}\n", mrc_size_text(c.knee.capacity, c.unit), c.knee.capacity,
                 unit, c.knee.miss_ratio);
    else
      fmt::print("knee: none (the curve is straight or concave)\n");
    if (c.unit == MrcUnit::kBytes && c.max_size > 1)
      fmt::print("note: below the largest access ({}) an LruCache rejects entries: there the curve is an upper bound\n",
                 human_bytes(static_cast<double>(c.max_size)));
    if (c.size_changes > 0)
      fmt::print("note: {} re-accesses changed their key's size; each counts as a miss at every size\n", c.size_changes);
  }
  if (a.json || !a.json_file.empty()) {
    nlohmann::json j = mrc_json(c, source);
    if (!opt.empty())
      for (std::size_t i = 0; i < opt.size(); ++i) j["curve"][i]["belady_miss_ratio"] = opt_ratio(i);
    if (!a.json_file.empty()) write_output(a.json_file, j.dump(2) + "\n");
    if (a.json) fmt::print("{}\n", j.dump(2));
  }
  if (!a.csv.empty()) {
    std::string csv = fmt::format("capacity_{},miss_ratio\n", unit);
    for (std::size_t i = 0; i < c.capacity.size(); ++i) csv += fmt::format("{},{}\n", c.capacity[i], c.miss_ratio[i]);
    mrc_write_text(a.csv, csv);
  }
  if (!a.svg.empty()) {
    std::vector<MrcChartSeries> series = {{c.shards_rate > 0 ? fmt::format("LRU, SHARDS {:g}", c.shards_rate) : "LRU", c}};
    if (!opt.empty()) {
      MissRatioCurve b = c;
      for (std::size_t i = 0; i < opt.size(); ++i) b.miss_ratio[i] = opt_ratio(i);
      b.knee = find_knee(b.capacity, b.miss_ratio);
      series.push_back({"Belady", b});
    }
    mrc_write_text(a.svg, mrc_chart_svg(series, "Miss-ratio curve: " + source));
  }
}

void run_mrc(const MrcArgs& a) {
  MrcOptions o;
  if (a.unit.empty() || a.unit == "pages") o.unit = MrcUnit::kPages;
  else if (a.unit == "bytes") o.unit = MrcUnit::kBytes;
  else throw InputError("--unit", fmt::format("'{}' is not pages or bytes", a.unit));
  if (a.shards) {
    const double r = *a.shards;
    if (!(r > 0 && r <= 1) || std::round(r * static_cast<double>(kShardsModulus)) < 1)
      throw InputError("--shards", fmt::format("rate {} is outside (0, 1] (a sampling rate; at least 2^-25)", r));
    o.shards_rate = r;
  }
  check_output("--json-file", a.json_file);
  check_output("--csv", a.csv);
  check_output("--svg", a.svg);
  check_output("--record", a.record);
  if (a.json && (a.json_file == "-" || a.csv == "-" || a.svg == "-"))
    throw InputError("--json", "prints to stdout already: give --json-file / --csv / --svg a file");
  if (a.sizes < 2 || a.sizes > kMrcMaxSizes)
    throw InputError("--sizes", fmt::format("{} is outside [2, {}]", a.sizes, kMrcMaxSizes));
  o.points = static_cast<std::size_t>(a.sizes);
  if (a.accesses.empty() == a.trace.empty())
    throw InputError(a.trace.empty() ? "--accesses" : "--trace",
                     "give either an access file (--accesses) or a replay to record (--trace, with --config/--set)");
  if (a.trace.empty() && (!a.level.empty() || !a.configs.empty() || !a.sets.empty() || !a.system.empty()))
    throw InputError(!a.level.empty() ? "--level" : !a.configs.empty() ? "--config" : !a.sets.empty() ? "--set" : "--system",
                     "configures a replay to record: give --trace");
  if (!a.trace.empty() && !a.unit.empty())
    throw InputError("--unit", "a replay's level sets the unit (--level pool: pages, --level ram: bytes)");
  // Belady runs once per printed size, O(n log n) each: a long curve of Belady passes would run for hours.
  constexpr int kMrcMaxOptSizes = 65;
  if (a.opt && a.sizes > kMrcMaxOptSizes)
    throw InputError("--sizes", fmt::format("{} with --opt: at most {} (one Belady pass per size)", a.sizes, kMrcMaxOptSizes));
  AccessLog log;
  std::string source = a.accesses;
  if (!a.trace.empty()) {
    if (std::find(a.configs.begin(), a.configs.end(), "-") != a.configs.end() && a.trace == "-")
      throw InputError("--config", "--config - and --trace - cannot both read stdin");
    const ReplayConfig cfg = with_inputs(a.configs, "--config", false,
                                         [&](const std::vector<std::string>& p) { return load_replay_config(p, a.sets, a.system); });
    const Trace trace = load_cli_trace(a.trace, a.allow_repairs);
    std::string level = a.level.empty() ? std::string(streaming_systems().at(cfg.run.system).caps.mrc_level) : a.level;
    if (level != "ram" && level != "pool") throw InputError("--level", fmt::format("'{}' is not ram or pool", level));
    RecordedReplay r = record_accesses(cfg, trace);
    if (level == "pool" && r.accesses.pool.frame_start.empty())
      throw InputError("--level", fmt::format("the {} system has no page pool (use --level ram)", cfg.run.system));
    log = std::move(level == "pool" ? r.accesses.pool : r.accesses.ram);
    o.unit = level == "pool" ? MrcUnit::kPages : MrcUnit::kBytes;  // the level's own unit
    source = fmt::format("{} ({}, {} level)", a.trace, cfg.run.system, level);
    if (!a.record.empty()) write_access_file(a.record, log);
  } else {
    if (!a.record.empty()) throw InputError("--record", "records a replay's accesses: give --trace");
    log = with_input(a.accesses, [](const std::string& p) { return read_access_file(p); });
  }
  MissRatioCurve c;
  try {
    c = miss_ratio_curve(log.accesses, o);
  } catch (const std::invalid_argument& e) {  // sizes summing beyond 2^63
    throw InputError(source, e.what());
  }
  std::vector<std::uint64_t> opt;
  if (a.opt) {  // Belady at each printed size: MIN with optional admission (pages), Belady-Size (bytes)
    try {
      for (std::uint64_t cap : c.capacity)
        opt.push_back(o.unit == MrcUnit::kPages ? belady_min_bypass(log.accesses, cap).misses
                                                : belady_size(log.accesses, cap).misses);
    } catch (const std::invalid_argument& e) {  // a capacity beyond 2^62 bytes
      throw InputError(source, e.what());
    }
  }
  report_mrc(c, source, a, opt);
}

}  // namespace

void register_mrc_commands(CLI::App& app) {
  auto a = std::make_shared<MrcArgs>();
  auto* c = app.add_subcommand("mrc", "LRU miss-ratio curve of an access sequence at every cache size, exact or by "
                                      "SHARDS sampling, with its knee (docs/cache.md)");
  c->add_option("--accesses", a->accesses, "access file: 'key [size]' per line, keys decimal or 0x-hex, '#' comments (- for stdin)");
  c->add_option("--trace,-t", a->trace, "or record a simulated replay of this trace (with --config, --set, --system)");
  c->add_option("--config,-c", a->configs, "replay: TOML config file (docs/config.md; - for stdin); repeatable: files read in order, a later one overriding an earlier one's keys")->allow_extra_args(false);
  c->add_option("--set", a->sets, "replay: override one config key (repeatable)");
  c->add_option("--system", a->system, "replay: " + streaming_systems().names(" | ") + " (overrides run.system)");
  c->add_option("--level", a->level, "replay: ram (bytes) | pool (VT pages); default pool for vt, ram otherwise");
  c->add_option("--record", a->record, "replay: also write the level's accesses to this access file");
  c->add_flag("--allow-repairs", a->allow_repairs, kAllowRepairsHelp);
  c->add_flag("--opt", a->opt, "also Belady's misses at each printed size (pages: MIN with optional admission; bytes: "
                               "Belady-Size, an upper bound on the optimum)");
  c->add_option("--unit", a->unit, "access file: pages (every access weighs 1, the default) | bytes (an access weighs its size)");
  c->add_option("--shards", a->shards, "SHARDS sampling rate in (0, 1], e.g. 0.01 (default: exact)");
  c->add_option("--sizes", a->sizes, "cache sizes printed, evenly spaced from 0 to the footprint")->capture_default_str();
  c->add_flag("--json", a->json, "print the curve and knee as JSON instead of the table");
  c->add_option("--json-file", a->json_file, "write the curve and knee as JSON to this file (- for stdout)");
  c->add_option("--csv", a->csv, "write the curve as CSV (capacity,miss_ratio) to this file (- for stdout)");
  c->add_option("--svg", a->svg, "write an SVG chart of the curve to this file (- for stdout)");
  c->callback([a] { run_mrc(*a); });
}

}  // namespace vtsim::cli
