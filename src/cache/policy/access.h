#pragma once
// One request of a recorded access sequence: what the offline simulator, Belady's bound and the
// miss-ratio curves replay (docs/cache.md, "Replacement policies"). A replay records one sequence
// per cache level: the RAM tier (size = the tile's decoded bytes) and the VT page pool (size = 1).
#include <cstdint>
#include <vector>

namespace vtsim {

struct Access {
  std::uint64_t key = 0;   // TileKey::bits (RAM) or the page's TileKey::bits (pool)
  std::uint64_t size = 1;  // bytes (RAM) or 1 (pool)
};

// A level's sequence with its frame boundaries: frame_start[f] is the index of the first access
// of frame f (non-decreasing; accesses.size() closes the last frame).
struct AccessLog {
  std::vector<Access> accesses;
  std::vector<std::uint64_t> frame_start;
};

}  // namespace vtsim
