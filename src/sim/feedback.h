#pragma once
// Feedback aggregation (seed 001 §3.1): the set of tiles a frame's samples touch, per mip level,
// with how many samples touched each — what a virtual-texturing system requests and a clipmap
// uses to decide which levels are needed.
#include <cstdint>
#include <vector>

#include "core/tile_key.h"
#include "sim/view.h"

namespace vtsim {

struct TileUse {
  TileKey key;                // layer 0, level = desired_level(lod), x = (u >> level) / tile size, y alike
  std::uint32_t samples = 0;  // feedback samples that touched the tile
};

// Fills `out` with the touched tiles sorted by key (`out` is cleared first; its storage and a
// per-thread hash table are reused, so steady-state calls do not allocate). Cost O(samples + runs
// + tiles·log tiles): consecutive samples of a row that map to the same tile are counted as one
// run before a hash lookup merges runs across rows. Thread-safe for distinct `out`.
// Throws std::invalid_argument for tile_size_texels outside [1, 2^24], num_levels outside
// [1, 64], or a sample whose tile does not fit a TileKey (negative texel, beyond 2^27 tiles).
void aggregate_feedback(const ViewBuffer& vb, int tile_size_texels, int num_levels, std::vector<TileUse>& out);

}  // namespace vtsim
