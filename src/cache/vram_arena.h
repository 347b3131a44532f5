#pragma once
// The VRAM arena: host memory standing in for the GPU's texture memory in the real clock. The
// upload stage copies each decoded tile chosen within the frame's upload budget into it — the
// memcpy a driver's staging upload would do. Layout mirrors the clipmap's textures (Yao 2007
// §3-2): per level a window of wx × wy tile slots addressed toroidally, (x mod wx, y mod wy), one
// slot per layer, so a tile overwrites exactly the slot of the tile that left its window. Or the
// physical page pool of virtual texturing (for_pool): M slots of one stored page (P + 2B texels a
// side) per layer, where the streaming system, not the key, says which slot a page fills
// (IStreamingSystem::vram_slot).
//
// Memory: sum over levels of wx · wy · Σ layer tile bytes (pool: M · Σ layer tile bytes),
// allocated and zeroed up front. upload O(tile bytes); peek O(1). Single-threaded (the frame loop).
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

#include "cache/clipmap.h"
#include "core/host_memory.h"
#include "core/tile_data.h"

namespace vtsim {

class VramArena {
 public:
  struct LevelWindow {
    std::int64_t wx = 1, wy = 1;  // window size, tiles
  };
  // `layer_bytes[i]`: decoded bytes of one tile of layer i (> 0). An arena whose texels and
  // bookkeeping (16 bytes a slot) exceed `host_limit` bytes (default: usable_memory_bytes(), the
  // machine's physical memory or its cgroup's limit) throws ArenaTooLarge before anything is
  // allocated: under overcommit the allocation itself would succeed and zeroing it would bring in
  // the OOM killer. (One just below the limit can still meet it: the check is against the limit,
  // not what is free.)
  VramArena(std::vector<LevelWindow> levels, std::vector<std::uint32_t> layer_bytes,
            std::uint64_t host_limit = usable_memory_bytes());
  // The arena of a clipmap's stack windows and pyramid levels.
  static VramArena for_clipmap(const ClipmapParams& p, std::vector<std::uint32_t> layer_bytes,
                               std::uint64_t host_limit = usable_memory_bytes());
  // A virtual texture's physical page pool of `slots` pages.
  static VramArena for_pool(std::uint32_t slots, std::vector<std::uint32_t> layer_bytes,
                            std::uint64_t host_limit = usable_memory_bytes());
  struct ArenaTooLarge : std::length_error {
    ArenaTooLarge(std::uint64_t need, std::uint64_t limit);
    std::uint64_t bytes = 0, limit = 0;
  };
  bool pool() const { return pool_; }

  // Copies `tile` into its slot, replacing whatever tile held it: the slot its key addresses, or in
  // a pool arena pool slot `pool_slot` (its layer's part). Throws std::invalid_argument if the
  // tile's level, layer or pool slot is outside the arena, a pool slot is missing (or given to a
  // window arena), or its size is not the layer's.
  void upload(const TileData& tile, std::int64_t pool_slot = -1);
  // The texels of `key` if its slot (in a pool arena: pool slot `pool_slot`) holds that tile now;
  // empty otherwise.
  std::span<const std::uint8_t> peek(TileKey key, std::int64_t pool_slot = -1) const;

  std::uint64_t capacity_bytes() const { return bytes_; }
  struct Stats {
    std::uint64_t uploads = 0;     // tiles copied in
    std::uint64_t bytes = 0;       // bytes copied in
    std::uint64_t overwrites = 0;  // uploads that replaced another resident tile
    std::int64_t copy_ns = 0;      // wall time spent copying
  };
  const Stats& stats() const { return stats_; }

 private:
  std::size_t slot(TileKey key, std::int64_t pool_slot) const;

  std::vector<LevelWindow> levels_;
  std::vector<std::uint32_t> layer_bytes_;
  std::vector<std::uint64_t> level_base_;  // first slot of each level
  std::vector<std::uint64_t> slot_offset_; // byte offset of each slot (slots of a tile's layers are adjacent)
  std::vector<TileKey> owner_;             // tile held by each slot; kNone if empty
  std::unique_ptr<std::uint8_t[]> mem_;
  std::uint64_t bytes_ = 0;
  bool pool_ = false;
  Stats stats_;
};

}  // namespace vtsim
