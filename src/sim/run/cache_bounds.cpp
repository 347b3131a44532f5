#include "sim/run/cache_bounds.h"

#include <vector>

#include "cache/policy/belady.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/mrc.h"
#include "cache/policy/simulate.h"
#include "core/tile_key.h"

namespace vtsim {

nlohmann::json level_bounds(const AccessLog& log, const LevelBoundsInput& in) {
  std::vector<Access> acc;
  std::vector<std::uint64_t> frame_start;  // the log's frames, renumbered past the dropped accesses
  acc.reserve(log.accesses.size());
  frame_start.reserve(log.frame_start.size());
  std::uint64_t locked = 0;
  std::size_t f = 0;
  for (std::size_t i = 0; i < log.accesses.size(); ++i) {
    while (f < log.frame_start.size() && log.frame_start[f] <= i) {
      frame_start.push_back(acc.size());
      ++f;
    }
    const Access& a = log.accesses[i];
    TileKey k;
    k.bits = a.key;
    if (in.pages && static_cast<int>(k.level()) >= in.locked_from_level) {
      ++locked;
      continue;
    }
    acc.push_back(a);
  }
  nlohmann::json j = {{"accesses", acc.size()}, {"accesses_locked", locked}, {"capacity", in.capacity}, {"policy", in.policy}};
  if (in.pages) {
    // The pool's rules: pages requested this frame are pinned, a miss with every page pinned goes
    // without. MIN with optional admission bounds every policy under them.
    const auto framed = [&](std::string_view name) {
      const auto p = make_replacement_policy(name, in.capacity);
      return simulate_frames(acc, frame_start, *p, in.capacity).misses;
    };
    j["policy_offline_misses"] = framed(in.policy);
    j["lru_offline_misses"] = framed("lru");
    j["opt_misses"] = belady_min_bypass(acc, in.capacity).misses;
  } else {
    j["policy_offline_misses"] = simulate(acc, in.policy, in.capacity).misses;
    j["lru_offline_misses"] = simulate(acc, "lru", in.capacity).misses;
    j["opt_misses_upper"] = belady_size(acc, in.capacity).misses;
    j["opt_misses_lower"] = pfoo_lower(acc, in.capacity).misses;
  }
  MrcOptions mo;
  mo.unit = in.pages ? MrcUnit::kPages : MrcUnit::kBytes;
  mo.points = in.curve_points;
  // The curve over every access, locked pages included: its sizes read as vt.pool_pages directly.
  const MissRatioCurve c = miss_ratio_curve(log.accesses, mo);
  nlohmann::json knee = nullptr;
  if (c.knee.found) knee = {{"capacity", c.knee.capacity}, {"miss_ratio", c.knee.miss_ratio}};
  j["mrc"] = {{"unit", mrc_unit_name(c.unit)}, {"capacity", c.capacity}, {"miss_ratio", c.miss_ratio}, {"knee", knee}};
  return j;
}

}  // namespace vtsim
