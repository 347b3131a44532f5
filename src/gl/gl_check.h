#pragma once
// The GPU's feedback against a simulated ViewBuffer (docs/gpu.md, "Checks"): per pixel, whether
// both sides have a sample and want the same level and tile; per frame, the Jaccard index of the
// requested tile sets {(level, tile x, tile y)}.
#include <cstdint>
#include <set>
#include <tuple>
#include <vector>

#include "core/view.h"
#include "gl/gl_renderer.h"

namespace vtsim::gl {

using TileSet = std::set<std::tuple<int, std::int64_t, std::int64_t>>;

// Per feedback pixel: desired level (−1: no sample) and tile at that level.
struct PerPixel {
  std::vector<int> level;
  std::vector<std::int64_t> tx, ty;
  TileSet tiles;
};
PerPixel per_pixel(const ViewBuffer& vb, int levels, int tile_size);
PerPixel per_pixel(const FeedbackFrame& f, int levels, int tile_size);

struct Agreement {
  std::uint64_t either = 0;     // pixels with a sample on either side
  std::uint64_t same = 0;       // of those, a sample on both with the same level and tile
  std::uint64_t level_off = 0;  // a sample on both, levels differ
  double jaccard = 1.0;         // |A ∩ B| / |A ∪ B| of the tile sets (1 when both are empty)
  double same_fraction() const { return either == 0 ? 1.0 : static_cast<double>(same) / static_cast<double>(either); }
};
Agreement agree(const PerPixel& a, const PerPixel& b);

}  // namespace vtsim::gl
