#pragma once
// What the recorded accesses of a replay say about its caches (`metrics.opt`, `vtsim replay
// --opt`; docs/cache.md, "Bounds in a replay"): per level (RAM in bytes, the VT pool in pages),
// the same accesses replayed offline through the run's own policy, through LRU, and through
// Belady's bound at the run's capacity, and the exact LRU miss-ratio curve. The offline replays
// fill a miss at once, so they measure the policy, not the pipeline: the gap between the live
// misses and the offline ones is what timing (a page still loading counts a miss each frame it is
// wanted) and throttling add. The pool's offline replays keep its rules (pages requested this
// frame pinned, a miss with every page pinned goes without: simulate_frames) and its bound is MIN
// with optional admission; RAM's are plain (simulate), bracketed by Belady-Size and PFOO-L.
#include <nlohmann/json.hpp>
#include <cstdint>
#include <string_view>

#include "cache/policy/access.h"

namespace vtsim {

struct LevelBoundsInput {
  std::string_view policy;        // the run's policy at this level (replacement_policies())
  std::uint64_t capacity = 0;     // bytes (RAM) or pool slots free for unlocked pages
  bool pages = false;             // unit sizes: Belady's MIN is exact; else Belady-Size and PFOO-L bracket OPT
  int locked_from_level = 64;     // pool: accesses to pages at this level or coarser are dropped (always resident)
  std::size_t curve_points = 33;  // sampled capacities of the miss-ratio curve
};

// {"accesses", "accesses_locked", "capacity", "policy", "policy_offline_misses", "lru_offline_misses",
//  "opt_misses" (pages) or "opt_misses_upper"/"opt_misses_lower" (bytes), "mrc": {"unit", "capacity",
//  "miss_ratio", "knee"}}. O(n log n) in the accesses.
nlohmann::json level_bounds(const AccessLog& log, const LevelBoundsInput& in);

}  // namespace vtsim
