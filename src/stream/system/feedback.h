#pragma once
// Feedback aggregation (Yao 2011 §3.1): the set of tiles a frame's samples touch, per mip level,
// with how many samples touched each — what a virtual-texturing system requests and a clipmap
// uses to decide which levels are needed.
#include <cstdint>
#include <vector>

#include "core/tile_key.h"
#include "core/view.h"
#include "core/view_spans.h"

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

// The same result from a span buffer: one table update per span whose bounding box lies in one
// tile (every span when the tile size is a power of two >= 2^block_shift), the span's samples
// (expand_span) otherwise. Cost O(spans + tiles·log tiles). Throws like the above, and
// std::invalid_argument when num_levels exceeds sb.levels (the spans' levels would be clamped).
void aggregate_feedback(const SpanBuffer& sb, int tile_size_texels, int num_levels, std::vector<TileUse>& out);

// Conservative completion of a low-resolution buffer's tile set ("level seams", docs/view.md).
// Where two neighbouring buffer samples (left/right or up/down) have desired levels l1 < l2, the
// full-resolution pixels between them take every level in [l1, l2] — most visibly near the
// horizon, where each full-resolution row has its own coarse level. For such a pair on one
// continuous surface (level-0 texel distance at most 4·divisor·2^l2 on both axes; farther apart
// it is a silhouette and nothing is added), each sample's texel is added at every level of
// [l1, l2]. `out` must be aggregate_feedback's sorted output for the same buffer; added tiles
// carry samples = 0 and `out` stays sorted. Returns the number of tiles added. Cost O(samples).
// Throws std::invalid_argument like aggregate_feedback.
std::size_t add_level_seams(const ViewBuffer& vb, int tile_size_texels, int num_levels, std::vector<TileUse>& out);

}  // namespace vtsim
