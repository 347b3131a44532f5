#pragma once
// What a residency structure asks the pipeline for: one tile needed this frame with its priority.
// The clipmap's windows and the VT page pool emit needs (cache/, stream/system/); the request
// pipeline (stream/exec/pipeline.h) diffs them against what is in flight.
#include <cstdint>

#include "core/tile_key.h"

namespace vtsim {

// One needed tile for this frame. Priority: lower is more urgent (see make_priority).
struct Need {
  TileKey key;
  std::uint64_t priority = 0;
  bool prefetch = false;  // look-ahead: bring into RAM only, never upload
};

// Coarse before fine (Yao 2007: the coarser level is the fallback every sample needs), then by
// screen importance (samples that use the tile; more first), then by `tiebreak` (e.g. distance).
inline std::uint64_t make_priority(std::uint32_t level, std::uint64_t importance, std::uint32_t tiebreak = 0) {
  const std::uint64_t lvl = 63u - (level & 63u);
  const std::uint64_t imp = importance > 0xFFFFFFu ? 0xFFFFFFu : importance;
  const std::uint64_t tb = tiebreak > 0xFFFFFFu ? 0xFFFFFFu : tiebreak;
  return (lvl << 54) | ((0xFFFFFFu - imp) << 24) | tb;
}
// Prefetch sorts after every demand request.
inline constexpr std::uint64_t kPrefetchPriorityBase = std::uint64_t{1} << 62 | std::uint64_t{1} << 61;

}  // namespace vtsim
