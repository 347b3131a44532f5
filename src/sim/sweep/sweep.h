#pragma once
// Sweeps (docs/sweep.md): every config point of a spec on every trace, one row per (config,
// trace). View once, systems many: the points that share the view (the view key below) are
// stepped in lockstep on one rendered view per trace, so the feedback is rendered once per
// (trace, view group) instead of once per row, and each row is byte-identical to `vtsim replay`
// with that config alone (the summary without its "run" cost section).
//
// Rows are numbered row = trace_index * configs + config_index... see row_index(); the work is cut
// into tasks, one per (trace, view group, contiguous block of rows). A task's rows are written to
// OUT/parts/ when it completes (atomically), so a killed sweep restarted on the same OUT skips what
// it finished and redoes only the tasks that were in flight. A shard (I/N) is a contiguous block of
// the row order; `merge_sweep` joins the shards' parts into exactly the unsharded outputs.
//
// Thread-safety: run_sweep uses `jobs` threads of its own; the functions are not reentrant on
// one output directory.
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/sweep/sweep_spec.h"

namespace vtsim {

// What must be equal for two configs to share one rendered view: run.fps, the texture's
// placement and size, the scene, the [view] section but render_threads, and the tile size
// (spans never cross a tile).
std::string view_key(const ReplayConfig& cfg);

struct SweepShard {
  int index = 0;  // 0-based
  int count = 1;
};
// "I/N" (0 <= I < N) or "slurm" (SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN / SLURM_ARRAY_TASK_COUNT).
SweepShard parse_shard(const std::string& text, const std::string& where);

struct SweepOptions {
  std::string out_dir;
  int jobs = 0;                  // 0: one per core
  SweepShard shard;
  // An input changed since out_dir was written (a trace, scene file, base config, the build):
  // false refuses to run (InputError naming what changed); true re-runs the tasks that read it
  // and keeps the others (docs/sweep.md, "Resume").
  bool rerun_changed = false;
  // Progress, about once a second from the calling thread: rows done, rows of this shard, the
  // fraction of the work done (frames stepped), seconds elapsed, seconds left (estimate); and once
  // when the work is done (fraction 1).
  std::function<void(std::size_t, std::size_t, double, double, double)> progress;
};

struct SweepRunStats {
  std::size_t rows = 0;          // rows of this shard
  std::size_t rows_skipped = 0;  // already done (restart)
  std::size_t rows_failed = 0;   // rows whose replay failed (status "error")
  std::size_t rows_retried = 0;  // of the rows run now, those a previous run left failed
  std::size_t rows_changed = 0;  // of the rows run now, those whose inputs changed (rerun_changed)
  std::size_t tasks = 0, views_rendered = 0;
  double wall_s = 0, cpu_s = 0;  // this process
  double replayed_s = 0;         // trace seconds replayed, summed over rows run now
  std::vector<std::string> input_warnings;  // what the trace readers repaired (load_sweep_trace) and
                                            // the scene readers left out (IScene::load_warnings)
};

// Runs a shard of the sweep into opts.out_dir (OUT/parts/, OUT/shard.json); an unsharded run
// (count 1) also writes the joined outputs: rows.jsonl, rows.csv, report.html, sweep.json.
// Throws InputError for a trace that fails to load, an out dir of another spec.
SweepRunStats run_sweep(const SweepSpec& spec, const SweepOptions& opts);

// Joins shard directories into out_dir's joined outputs; refuses shards of another spec, a
// missing or duplicated shard, or an incomplete one (InputError naming the directory).
void merge_sweep(const std::vector<std::string>& shard_dirs, const std::string& out_dir);

// The spec's traces, loaded or generated; InputError naming spec:line and the trace. The readers'
// repairs are appended to *warnings when given (load_sweep_trace).
std::vector<Trace> load_sweep_traces(const SweepSpec& spec, std::vector<std::string>* warnings = nullptr);

// Replays the spec's points `configs` on every trace (the points sharing a view stepped in
// lockstep on it, `jobs` threads) and returns their rows as rows.jsonl has them: one vector per
// config, one row per trace.
std::vector<std::vector<nlohmann::json>> replay_points(const SweepSpec& spec, const std::vector<Trace>& traces,
                                                       const std::vector<int>& configs, int jobs);

// Throws InputError naming spec:line when a metric or tune constraint names no value of a replay
// summary (a short probe replay per system gives the summaries' keys); run_sweep checks this
// before it writes anything.
void check_sweep_metrics(const SweepSpec& spec, const std::vector<Trace>& traces);

// A sweep's identity (docs/sweep.md, "Resume"): `structure`, the hash of what the spec itself
// says (its name, expanded points, metrics, the number of traces); `inputs`, the content of
// everything else a row depends on, by name ("build", "base config", "trace 0 (walk.csv)",
// "scene.file q.obj", "terrain.brush_files b/*.png"), each {hash, what}; `config_inputs`, the
// input names each config point reads besides the build, base config and its trace; `hash`,
// all of it together (sweep.json's and shard.json's spec_hash).
struct SweepIdentity {
  std::string hash, structure;
  nlohmann::json inputs = nlohmann::json::object();
  std::vector<std::vector<std::string>> config_inputs;
  // The hash of the inputs the rows of `configs` on `trace` read (a part's "inputs").
  std::string task_inputs(int trace, const std::vector<int>& configs) const;
};
SweepIdentity sweep_identity(const SweepSpec& spec, const std::vector<Trace>& traces);

// sweep_identity(spec, traces).hash; hex.
std::string sweep_spec_hash(const SweepSpec& spec, const std::vector<Trace>& traces);

}  // namespace vtsim
