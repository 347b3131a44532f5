// vtsim sweep: many configs × many traces, the view rendered once per trace and view group, on
// every core or as shards joined by `vtsim sweep merge` (docs/sweep.md).
#include <fmt/format.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "sim/sweep/sweep.h"
#include "sim/sweep/sweep_table.h"
#include "sim/sweep/tune.h"
#include "sim/run/real_replay.h"
#include "stream/store/tile_store.h"

namespace vtsim::cli {

namespace {

struct SweepArgs {
  std::string spec, out = "sweep-out", shard;
  int jobs = 0;
  bool quiet = false, progress = false, json = false, rerun_changed = false;
};

void run_sweep_command(const SweepArgs& a) {
  if (a.spec.empty()) throw InputError("sweep", "a spec file is required: vtsim sweep SPEC.toml -o OUT (docs/sweep.md)");
  if (a.jobs < 0) throw InputError("--jobs", "must be >= 0 (0: one per core)");
  check_output_dir("-o", a.out);  // before the work: created (its last level) once the inputs are read
  const SweepSpec spec = load_sweep_spec(a.spec);
  SweepOptions o;
  o.out_dir = a.out;
  o.jobs = a.jobs;
  o.rerun_changed = a.rerun_changed;
  if (!a.shard.empty()) o.shard = parse_shard(a.shard, "--shard");
  // A terminal gets one line rewritten each second; a log (--progress) a line every 10 s.
  const bool tty = isatty(fileno(stderr)) != 0;
  if (!a.quiet && (a.progress || tty))
    o.progress = [tty, last = -10.0](std::size_t done, std::size_t rows, double frac, double el, double eta) mutable {
      if (!tty && el - last < 10.0 && done < rows) return;  // the last report always shows
      last = el;
      fmt::print(stderr, "{}sweep: {:.0f}% ({}/{} rows done), {:.0f} s elapsed, ~{:.0f} s left{}", tty ? "\r" : "",
                 100.0 * frac, done, rows, el, eta, tty ? "   " : "\n");
    };
  if (!a.quiet)
    fmt::print(stderr, "sweep '{}': {} configs × {} traces{}\n", spec.name.empty() ? a.spec : spec.name,
               spec.points.size(), spec.traces.size(),
               o.shard.count > 1 ? fmt::format(", shard {}/{}", o.shard.index, o.shard.count) : std::string());
  const SweepRunStats st = run_sweep(spec, o);
  if (o.progress && tty) fmt::print(stderr, "\r{:70}\r", "");
  for (const std::string& w : st.input_warnings) warn(w);
  if (a.json) {  // the run's own record: what sweep.json (or the shard's record) holds, and this run's counts
    const nlohmann::json j = {{"rows", st.rows}, {"rows_run", st.rows - st.rows_skipped}, {"rows_skipped", st.rows_skipped},
                              {"rows_failed", st.rows_failed}, {"rows_retried", st.rows_retried},
                              {"rows_changed", st.rows_changed}, {"tasks", st.tasks}, {"wall_s", st.wall_s}, {"cpu_s", st.cpu_s},
                              {"out", a.out}, {"shard", {{"index", o.shard.index}, {"count", o.shard.count}}}};
    fmt::print("{}\n", j.dump(2));
  }
  if (a.quiet || a.json) {
    if (st.rows_failed > 0) throw Exit{kExitFailure};
    return;
  }
  fmt::print("{} rows ({} run now, {} already done, {} failed) in {} tasks: {:.1f} s wall, {:.1f} s CPU", st.rows,
             st.rows - st.rows_skipped, st.rows_skipped, st.rows_failed, st.tasks, st.wall_s, st.cpu_s);
  if (st.cpu_s > 0 && st.replayed_s > 0) fmt::print(", {:.0f}x real time per row on one core", st.replayed_s / st.cpu_s);
  fmt::print("\n");
  if (st.rows_retried > 0 || st.rows_changed > 0)
    fmt::print("of the rows run now, {} had failed before (retried) and {} read an input that changed\n", st.rows_retried,
               st.rows_changed);
  if (o.shard.count == 1)
    fmt::print("wrote {0}/rows.jsonl, {0}/rows.csv, {0}/report.html, {0}/sweep.json\n", a.out);
  else
    fmt::print("wrote shard {}/{} to {} (join the shards with `vtsim sweep merge -o OUT DIR...`)\n", o.shard.index,
               o.shard.count, a.out);
  if (st.rows_failed > 0) throw Exit{kExitFailure};
}

}  // namespace

void register_sweep_commands(CLI::App& app) {
  auto a = std::make_shared<SweepArgs>();
  auto* c = app.add_subcommand("sweep", "Replay many configs × many traces: rows, CSV and a report (docs/sweep.md)");
  c->add_option("spec", a->spec, "sweep spec (TOML: traces, base config, [grid] axes, [[configs]])");
  c->add_option("-o,--out", a->out, "output directory (rows.jsonl, rows.csv, report.html; restartable)")->capture_default_str();
  c->add_option("--jobs,-j", a->jobs, "threads (0: one per core)")->capture_default_str();
  c->add_option("--shard", a->shard, "run the slice I/N (0-based) of the work, or 'slurm' (from SLURM_ARRAY_TASK_*)");
  c->add_flag("--quiet,-q", a->quiet, "print no information (files are still written; warnings still are)");
  c->add_flag("--json", a->json, "print the run's counts as JSON on stdout instead of the text");
  c->add_flag("--progress", a->progress, "show progress even when stderr is not a terminal");
  c->add_flag("--rerun-changed", a->rerun_changed,
              "on an -o written before a trace, scene file, base config or the build changed: re-run the rows that read "
              "it (without: refused)");
  c->footer("A killed sweep restarted with the same -o skips the tasks it finished and retries failed rows; an -o in use "
            "by another sweep is refused. Exit 1 when a row failed.");

  auto merge_dirs = std::make_shared<std::vector<std::string>>();
  auto merge_out = std::make_shared<std::string>();
  auto* m = c->add_subcommand("merge", "Join shard directories into the outputs of the unsharded sweep");
  m->add_option("shards", *merge_dirs, "shard directories (every shard of one spec, once)")->required();
  m->add_option("-o,--out", *merge_out, "output directory")->required();
  m->callback([merge_dirs, merge_out] {
    check_output_dir("-o", *merge_out);
    merge_sweep(*merge_dirs, *merge_out);
    fmt::print("merged {} shards into {}/rows.jsonl, rows.csv, report.html, sweep.json\n", merge_dirs->size(), *merge_out);
  });
  auto table_dir = std::make_shared<std::string>();
  auto table = std::make_shared<SweepTableSpec>();
  auto table_rows = std::make_shared<std::string>();
  auto* t = c->add_subcommand("table", "Print a sweep's metrics as pivot tables (Markdown or CSV): lines by --rows, columns by --col");
  t->add_option("dir", *table_dir, "a sweep's output directory (sweep.json, rows.jsonl)")->required();
  t->add_option("--rows", *table_rows, "keys that make a line, comma-separated: trace, config or spec axes")->required();
  t->add_option("--col", table->col, "the key whose values make the columns, or metric: one table, a column per metric")->required();
  t->add_option("--metric", table->metrics, "a dotted summary path (repeatable: one table each)")->required();
  t->add_flag("--csv", table->csv, "CSV (metric, row keys, column, value) instead of Markdown");
  t->add_option("--digits", table->digits, "significant digits of a cell")->capture_default_str();
  t->callback([table_dir, table, table_rows] {
    if (table->digits < 1 || table->digits > 17) throw InputError("--digits", "must be in [1, 17]");
    table->rows.clear();
    std::string k;
    for (char ch : *table_rows + ",") {
      if (ch != ',') { k += ch; continue; }
      if (k.empty()) throw InputError("--rows", "an empty key in '" + *table_rows + "'");
      table->rows.push_back(k);
      k.clear();
    }
    fmt::print("{}", sweep_table(load_sweep_outputs(*table_dir), *table));
  });
  c->callback([a, m, t] {
    if (m->parsed() || t->parsed()) return;
    run_sweep_command(*a);
  });
}

}  // namespace vtsim::cli

namespace vtsim::cli {

namespace {

struct TuneArgs {
  std::string spec, out = "tune-out", store;
  int jobs = 0;
  bool quiet = false, json = false;
};

void run_tune_command(const TuneArgs& a) {
  if (a.jobs < 0) throw InputError("--jobs", "must be >= 0 (0: one per core)");
  check_output_dir("-o", a.out);  // before the search: created (its last level) once it is done
  const SweepSpec spec = load_sweep_spec(a.spec);
  std::vector<std::string> trace_warnings;
  const std::vector<Trace> traces = load_sweep_traces(spec, &trace_warnings);
  for (const std::string& w : trace_warnings) warn(w);
  check_sweep_metrics(spec, traces);
  if (!a.store.empty()) {  // refused now, not after the search: a store that opens and fits a config
    const TileStore store = TileStore::open(a.store);
    std::string why;
    for (const SweepPoint& p : spec.points) {
      ReplayConfig c = p.cfg;
      try {
        (void)bind_store_texture(c, store);
        why.clear();
        break;
      } catch (const InputError& e) {
        if (why.empty()) why = e.what();
      }
    }
    if (!why.empty()) throw InputError(a.store, "fits no config of the grid (config 0: " + why + ")");
  }
  std::size_t replays = 0;
  const bool show = !a.quiet && isatty(fileno(stderr)) != 0;
  const TuneResult r = run_tune(spec, [&](const std::vector<int>& configs) {
    replays += configs.size();
    if (show) fmt::print(stderr, "\rtune: {} configs replayed on {} traces", replays, traces.size());
    return replay_points(spec, traces, configs, a.jobs);
  });
  if (show) fmt::print(stderr, "\r{:60}\r", "");
  nlohmann::json out = {{"schema", "vtsim.tune/1"},
                        {"spec", a.spec},
                        {"grid", r.grid},
                        {"replayed", r.replayed.size()},
                        {"inferred", r.inferred},
                        {"monotonicity_failures", r.monotonicity_failures},
                        {"constraints", nlohmann::json::array()},
                        {"front", nlohmann::json::array()}};
  for (const auto& c : spec.tune.constraints) out["constraints"].push_back(c.text);
  std::string table = fmt::format("{:>6}", "config");
  for (const auto& k : spec.axis_keys) table += fmt::format("  {:>22}", k);
  for (const auto& c : spec.tune.constraints) table += fmt::format("  {:>22}", c.metric);
  table += "\n";
  for (int p : r.front) {
    nlohmann::json f = {{"config", p}, {"values", nlohmann::json::object()}, {"worst", r.replayed.at(p).worst}};
    table += fmt::format("{:>6}", p);
    for (const auto& [k, v] : spec.points[static_cast<std::size_t>(p)].values) {
      f["values"][k] = v;
      table += fmt::format("  {:>22}", v);
    }
    for (double w : r.replayed.at(p).worst) table += fmt::format("  {:>22.4g}", w);
    table += "\n";
    out["front"].push_back(std::move(f));
  }
  const int rec = recommended_config(spec, r.front);
  out["recommended"] = rec;
  make_output_dir("-o", a.out);
  const auto write = [&] {
    write_output((std::filesystem::path(a.out) / "tune.json").string(), out.dump(2) + "\n");
  };
  if (!a.store.empty() && rec >= 0) {
    write();  // the search's result is kept if the real-clock check fails (or is interrupted)
    out["real_check"] = tune_real_check(spec, traces, rec, a.store);
  }
  write();
  if (a.json) fmt::print("{}\n", out.dump(2));  // what tune.json holds
  if (a.quiet || a.json) return;
  fmt::print("{} configs meet every constraint at least cost (of {} in the grid); {} replayed ({:.0f}% of the grid), "
             "{} answered by monotonicity; {} monotonicity failures\n",
             r.front.size(), r.grid, r.replayed.size(), 100.0 * static_cast<double>(r.replayed.size()) / static_cast<double>(r.grid),
             r.inferred, r.monotonicity_failures.size());
  if (!r.front.empty()) fmt::print("{}", table);
  if (rec >= 0) fmt::print("recommended: config {}\n", rec);
  if (out.contains("real_check")) {
    const auto& rc = out["real_check"];
    fmt::print("real clock on {}: simulated {}, real {}\n", a.store, rc["sim_pass"].get<bool>() ? "passes" : "fails",
               rc["real_pass"].get<bool>() ? "passes" : "fails");
    for (const auto& c : rc["constraints"])
      fmt::print("  {:<40} simulated {:>10.4g}  real {:>10.4g}  gap {:+.4g}\n", c["constraint"].get<std::string>(),
                 c["sim"].get<double>(), c["real"].get<double>(), c["gap"].get<double>());
  }
  fmt::print("wrote {}/tune.json\n", a.out);
}

}  // namespace

void register_tune_commands(CLI::App& app) {
  auto a = std::make_shared<TuneArgs>();
  auto* c = app.add_subcommand("tune", "Find the cheapest configs of a sweep spec's grid that meet its [tune] constraints");
  c->add_option("spec", a->spec, "sweep spec with a [tune] section (docs/sweep.md, \"Tuning\")")->required();
  c->add_option("-o,--out", a->out, "output directory (tune.json)")->capture_default_str();
  c->add_option("--jobs,-j", a->jobs, "threads (0: one per core)")->capture_default_str();
  c->add_option("--store", a->store, "also replay the recommended config in the real clock on this tile store and report the gap");
  c->add_flag("--quiet,-q", a->quiet, "print no information (tune.json is still written; warnings still are)");
  c->add_flag("--json", a->json, "print what tune.json holds on stdout instead of the text");
  c->callback([a] { run_tune_command(*a); });
}

}  // namespace vtsim::cli
