#pragma once
// vtsim tune (docs/sweep.md, "Tuning"): the cheapest configs of a spec's [grid] that meet its
// [tune] constraints on every trace — the Pareto set under the cost axes' order — found with
// fewer replays than the grid by exploiting monotonicity: a config that meets the constraints
// still meets them with more of any cost (a bigger pool, more RAM, a larger upload budget).
//
// Search, per combination of the non-cost axes: the two longest cost axes are walked as a
// staircase (for each value of one, the cheapest passing value of the other only falls as the
// first grows: at most n1 + n2 replays per layer), the other cost axes are layers taken cheapest
// first; each query is first answered from the replays so far where monotonicity implies it. Then
// the front is checked where monotonicity was assumed: every config one step cheaper on one axis
// than a front config is replayed (if it was only inferred) and must fail; one that passes is
// reported as a monotonicity failure and joins the search, so the front returned is exact for
// every config next to it.
#include <cstddef>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/trace.h"
#include "sim/sweep/sweep_spec.h"

namespace vtsim {

// One config's verdict over every trace.
struct TuneVerdict {
  bool pass = false;
  std::vector<double> worst;      // per constraint: the worst value over the traces (NaN: missing)
  std::string failure;            // a row that failed to run, or the first constraint violated
};

// The verdict of config `index` given its rows (one per trace; status/summary as sweep rows).
TuneVerdict judge(const TuneSpec& tune, const std::vector<nlohmann::json>& rows);

struct TuneResult {
  std::vector<int> front;                  // spec.points indices, ascending
  std::map<int, TuneVerdict> replayed;     // every config replayed (on every trace), by index
  std::vector<int> monotonicity_failures;  // configs that passed although assumed to fail
  std::size_t grid = 0;                    // configs in the grid
  std::size_t inferred = 0;                // queries answered without a replay
};

// `evaluate(indices)` replays those configs on every trace and returns their rows (one vector
// per index, one row per trace). Throws InputError when the spec has no [tune] section or has
// [[configs]] (tune searches the grid).
TuneResult run_tune(const SweepSpec& spec,
                    const std::function<std::vector<std::vector<nlohmann::json>>(const std::vector<int>&)>& evaluate);

// The Pareto set by definition from a verdict per config (every config replayed): the passing
// configs no other passing config is cheaper-or-equal than on every cost axis (and equal on the
// other axes). For tests and the brute-force comparison.
std::vector<int> brute_force_front(const SweepSpec& spec, const std::vector<bool>& pass);

// Config a is no dearer than b on every cost axis and equal on the other axes.
bool cheaper_or_equal(const SweepSpec& spec, int a, int b);

// The recommended config of a front: the one cheapest on the cost axes together (the least sum of
// each axis's position in its list, 0 = cheapest, 1 = dearest); ties to the lower index. -1 for
// an empty front.
int recommended_config(const SweepSpec& spec, const std::vector<int>& front);

// Replays `config` on every trace in both clocks on the tile store at `store_path` (the texture
// bound to the store, the simulated clock sized by its tiles) and reports, per constraint, the
// worst value over the traces in each clock and their gap (real − simulated): whether to trust
// the simulated verdict on this machine. Real-clock replays take the traces' duration in wall time.
nlohmann::json tune_real_check(const SweepSpec& spec, const std::vector<Trace>& traces, int config,
                               const std::string& store_path);

}  // namespace vtsim
