// vtsim cachesim: replacement policies and Belady's bounds over an access file at listed
// capacities, as libCacheSim's cachesim (docs/cache.md, "Cache simulation on access files").
// Reads vtsim access files and libCacheSim's oracleGeneral and CSV traces.
#include <fmt/format.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "cache/policy/access_formats.h"
#include "cache/policy/access_io.h"
#include "cache/policy/cachesim.h"
#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/format.h"
#include "core/error.h"
#include "core/text.h"

namespace vtsim::cli {

namespace {

struct CachesimArgs {
  std::string accesses, format = "auto", policies = "lru,fifo,clock,arc,s3fifo,belady", sizes;
  // libCacheSim's csv reader options (traceReader/generalReader/csv.c)
  std::string obj_id_col, obj_size_col, time_col, delimiter;
  bool has_header = false, ignore_obj_size = false, json = false;
  std::string obj_id_is_num;  // empty: true
  std::string out, json_file, csv_file;
};

bool cachesim_ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// "auto": by the file name (libCacheSim's traces are named *.oracleGeneral.bin, *.oracleGeneral).
std::string cachesim_format(const CachesimArgs& a) {
  if (a.format != "auto") {
    if (a.format != "vtsim" && a.format != "oracleGeneral" && a.format != "csv")
      throw InputError("--format", fmt::format("'{}' is not auto, vtsim, oracleGeneral or csv", a.format));
    return a.format;
  }
  if (cachesim_ends_with(a.accesses, ".csv")) return "csv";
  if (a.accesses.find("oracleGeneral") != std::string::npos || cachesim_ends_with(a.accesses, ".bin")) return "oracleGeneral";
  return "vtsim";
}

std::string cachesim_capacity_text(std::uint64_t c, CapacityUnit u) {
  return u == CapacityUnit::kBytes ? human_bytes(static_cast<double>(c)) : fmt::format("{} objects", c);
}

double cachesim_ratio(std::uint64_t a, std::uint64_t b) { return b ? static_cast<double>(a) / static_cast<double>(b) : 0.0; }

void run_cachesim(const CachesimArgs& a) {
  const std::string format = cachesim_format(a);
  if (format != "csv") {
    for (const auto& [flag, v] : {std::pair<const char*, bool>{"--obj-id-col", !a.obj_id_col.empty()},
                                  {"--obj-size-col", !a.obj_size_col.empty()},
                                  {"--time-col", !a.time_col.empty()},
                                  {"--delimiter", !a.delimiter.empty()},
                                  {"--obj-id-is-num", !a.obj_id_is_num.empty()},
                                  {"--has-header", a.has_header}})
      if (v) throw InputError(flag, fmt::format("reads CSV traces; {} is read as {} (--format csv)", a.accesses, format));
  }
  CsvAccessOptions csv;
  if (format == "csv") {
    if (a.obj_id_col.empty()) throw InputError("--obj-id-col", "a CSV trace needs the object id's column (a 1-based number, or a header name with --has-header)");
    csv.obj_id_col = a.obj_id_col;
    csv.obj_size_col = a.obj_size_col;
    csv.time_col = a.time_col;
    csv.has_header = a.has_header;
    if (!a.delimiter.empty()) {
      if (a.delimiter == "\\t" || a.delimiter == "tab") csv.delimiter = '\t';
      else if (a.delimiter.size() == 1 && a.delimiter[0] != '"') csv.delimiter = a.delimiter[0];
      else throw InputError("--delimiter", fmt::format("'{}' is not one character (or \\t)", a.delimiter));
    }
    if (!a.obj_id_is_num.empty()) {
      if (a.obj_id_is_num == "true") csv.obj_id_is_num = true;
      else if (a.obj_id_is_num == "false") csv.obj_id_is_num = false;
      else throw InputError("--obj-id-is-num", fmt::format("'{}' is not true or false", a.obj_id_is_num));
    }
  }
  // Everything typed is checked before the file is read.
  std::vector<std::string> policies;
  {
    std::string_view p = a.policies;
    while (true) {
      const std::size_t c = p.find(',');
      const std::string name(text::trim(p.substr(0, c)));
      if (name.empty()) throw InputError("--policies", "an empty name (two commas in a row, or one at an end)");
      check_cachesim_policy(name, "--policies");
      for (const auto& q : policies)
        if (q == name) throw InputError("--policies", fmt::format("'{}' given twice", name));
      policies.push_back(name);
      if (c == std::string_view::npos) break;
      p.remove_prefix(c + 1);
    }
  }
  CapacityList caps = parse_capacity_list(a.sizes, "--sizes");
  if (a.ignore_obj_size && caps.unit_given && caps.unit == CapacityUnit::kBytes)
    throw InputError("--sizes", "byte capacities with --ignore-obj-size: give object counts");
  // -o by its extension, or --json-file / --csv (each may be - for stdout, instead of the table).
  std::string json_out = a.json_file, csv_out = a.csv_file;
  if (!a.out.empty()) {
    if (a.out == "-") throw InputError("-o", "give a file (.csv or .json), or --json-file - / --csv - for stdout");
    std::string& slot = cachesim_ends_with(a.out, ".csv") ? csv_out : json_out;
    if (!cachesim_ends_with(a.out, ".csv") && !cachesim_ends_with(a.out, ".json"))
      throw InputError("-o", fmt::format("'{}': the format is the extension, .csv or .json", a.out));
    if (!slot.empty()) throw InputError("-o", fmt::format("and {} both write it", &slot == &csv_out ? "--csv" : "--json-file"));
    slot = a.out;
  }
  check_output(a.out.empty() ? "--json-file" : "-o", json_out);
  check_output(a.out.empty() ? "--csv" : "-o", csv_out);
  const int to_stdout = (a.json ? 1 : 0) + (json_out == "-" ? 1 : 0) + (csv_out == "-" ? 1 : 0);
  if (to_stdout > 1) throw InputError("--json", "--json, --json-file - and --csv - each print to stdout: give one");

  AccessLog log;
  std::uint64_t zero_skipped = 0;
  bool sized = false;
  if (format == "oracleGeneral") {
    OracleGeneralRead r = with_input(a.accesses, [](const std::string& p) { return read_oracle_general(p); });
    log = std::move(r.log);
    zero_skipped = r.zero_size_skipped;
    sized = true;
  } else if (format == "csv") {
    log = with_input(a.accesses, [&](const std::string& p) { return read_access_csv(p, csv); });
    sized = !csv.obj_size_col.empty();
  } else {
    log = with_input(a.accesses, [](const std::string& p) { return read_access_file(p); });
    for (const Access& x : log.accesses) sized = sized || x.size != 1;
  }
  CapacityUnit unit = caps.unit_given ? caps.unit : (sized && !a.ignore_obj_size ? CapacityUnit::kBytes : CapacityUnit::kObjects);
  if (unit == CapacityUnit::kBytes && !sized)
    throw InputError("--sizes", fmt::format("byte capacities, but the requests of {} carry no sizes{}: give object counts",
                                            a.accesses, format == "csv" ? " (no --obj-size-col)" : " (all 1)"));
  const std::uint64_t footprint = access_footprint(log.accesses, unit);
  const std::uint64_t objects = unit == CapacityUnit::kObjects ? footprint : access_footprint(log.accesses, CapacityUnit::kObjects);
  resolve_capacities(caps, footprint, "--sizes");

  CacheSimReport rep;
  rep.source = a.accesses;
  rep.format = format;
  rep.unit = unit;
  rep.requests = log.accesses.size();
  rep.objects = objects;
  rep.footprint = footprint;
  rep.zero_size_skipped = zero_skipped;
  for (const auto& p : policies)
    for (const CapacityItem& c : caps.items) {
      try {
        rep.rows.push_back({p, c.token, c.value, cachesim_run(log.accesses, p, c.value, unit)});
      } catch (const std::invalid_argument& e) {
        throw InputError(a.accesses, e.what());
      }
    }
  const bool bytes = unit == CapacityUnit::kBytes;
  const char* unit_name = bytes ? "bytes" : "objects";
  if (!json_out.empty() || a.json) {
    const std::string j = cachesim_json(rep);
    if (!json_out.empty()) write_output(json_out, j);
    if (a.json) fmt::print("{}", j);
  }
  if (!csv_out.empty()) write_output(csv_out, cachesim_csv(rep));
  if (to_stdout) return;  // stdout holds that output, not the table
  fmt::print("{} ({}): {} requests, {} objects, footprint {}\n", a.accesses, format, log.accesses.size(), objects,
             cachesim_capacity_text(footprint, unit));
  if (zero_skipped) fmt::print("note: {} records of obj_size 0 skipped (as libCacheSim's reader does)\n", zero_skipped);
  fmt::print("{:<14} {:>18} {:>12} {:>12} {:>10}{}\n", "policy", fmt::format("capacity ({})", unit_name), "requests",
             "misses", "miss ratio", bytes ? fmt::format(" {:>16} {:>10}", "miss bytes", "byte ratio") : "");
  for (const CacheSimRow& r : rep.rows) {
    const SimStats& st = r.result.stats;
    fmt::print("{:<14} {:>18} {:>12} {:>12} {:>10.6f}{}{}\n", r.policy, r.capacity, st.requests, st.misses,
               cachesim_ratio(st.misses, st.requests),
               bytes ? fmt::format(" {:>16} {:>10.6f}", st.bytes_missed, cachesim_ratio(st.bytes_missed, r.result.bytes_requested))
                     : "",
               r.policy == "pfoo_lower" ? "  (a lower bound, not a policy)" : "");
  }
}

}  // namespace

void register_cachesim_commands(CLI::App& app) {
  auto a = std::make_shared<CachesimArgs>();
  auto* c = app.add_subcommand("cachesim", "replacement policies and Belady over an access file at the capacities listed, "
                                           "as libCacheSim's cachesim; reads its oracleGeneral and CSV traces (docs/cache.md)");
  c->add_option("--accesses,-a", a->accesses, "the requests: a vtsim access file, a libCacheSim oracleGeneral trace or a CSV "
                                              "trace (- for stdin)")->required();
  c->add_option("--format", a->format, "auto (by the name: *.csv, *oracleGeneral*, *.bin; else vtsim) | vtsim | oracleGeneral | csv")
      ->capture_default_str();
  c->add_option("--sizes,-s", a->sizes, "capacities, comma-separated: bytes (128MiB,1GiB; KB/MB/GB powers of 1000), object "
                                        "counts (1000,2000) or fractions of the footprint (0.01,0.1)")->required();
  c->add_option("--policies,-p", a->policies, "comma-separated: " + [] {
    std::string s;
    for (const auto& n : cachesim_policy_names()) s += (s.empty() ? "" : ", ") + n;
    return s;
  }())->capture_default_str();
  c->add_flag("--ignore-obj-size", a->ignore_obj_size, "every request weighs 1 (libCacheSim's --ignore-obj-size)");
  c->add_option("--obj-id-col", a->obj_id_col, "csv: the object id's column, 1-based or a header name (libCacheSim's obj-id-col)");
  c->add_option("--obj-size-col", a->obj_size_col, "csv: the size's column (none: every request weighs 1)");
  c->add_option("--time-col", a->time_col, "csv: the time's column (checked to be numbers, not used)");
  c->add_flag("--has-header", a->has_header, "csv: the first line names the columns");
  c->add_option("--delimiter", a->delimiter, "csv: the field separator, one character or \\t (default ,)");
  c->add_option("--obj-id-is-num", a->obj_id_is_num, "csv: true (default: decimal or 0x-hex ids) | false (any text, hashed)");
  c->add_option("-o,--out", a->out, "write the rows to this file, CSV or JSON by its extension (.csv, .json)");
  c->add_option("--json-file", a->json_file, "write the rows as JSON to this file (- for stdout)");
  c->add_option("--csv", a->csv_file, "write the rows as CSV to this file (- for stdout)");
  c->add_flag("--json", a->json, "print the rows as JSON instead of the table");
  c->callback([a] { run_cachesim(*a); });
}

}  // namespace vtsim::cli
