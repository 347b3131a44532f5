#pragma once
// A decoded tile in host memory: what the real clock's decode stage produces, the RAM cache holds
// (RamEntry::data) and the upload stage copies into the VRAM arena. The simulated clock carries no
// data (null pointers). Immutable once made; shared between the cache, the upload list and the
// arena's copy source through std::shared_ptr<const TileData>, so any thread may read it.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

#include "core/tile_key.h"

namespace vtsim {

struct TileData {
  TileKey key;
  std::uint32_t side = 0;      // texels per side, T + 2B
  std::uint32_t channels = 0;  // interleaved 8-bit channels
  std::size_t bytes = 0;       // side * side * channels
  std::unique_ptr<std::uint8_t[]> texels;

  std::span<const std::uint8_t> view() const { return {texels.get(), bytes}; }
};

}  // namespace vtsim
