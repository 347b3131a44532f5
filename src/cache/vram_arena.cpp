#include "cache/vram_arena.h"

#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string>

namespace vtsim {

namespace {
constexpr std::uint64_t kNone = ~std::uint64_t{0};  // no tile (not a valid packed key in use)
}

VramArena::ArenaTooLarge::ArenaTooLarge(std::uint64_t need, std::uint64_t lim)
    : std::length_error("VramArena: " + std::to_string(need) + " bytes, more than the " + std::to_string(lim) +
                        " bytes of memory this process may use"),
      bytes(need),
      limit(lim) {}

VramArena::VramArena(std::vector<LevelWindow> levels, std::vector<std::uint32_t> layer_bytes, std::uint64_t host_limit)
    : levels_(std::move(levels)), layer_bytes_(std::move(layer_bytes)) {
  if (levels_.empty() || layer_bytes_.empty()) throw std::invalid_argument("VramArena: no levels or layers");
  // Sizes first, checked before any allocation: tile counts overflow-checked, the bytes (texels
  // plus 16 bytes of bookkeeping a slot: offset and owner) in long double, exact below 2^64.
  long double page_bytes = 0.0L;  // one tile of every layer
  for (const std::uint32_t b : layer_bytes_) {
    if (b == 0) throw std::invalid_argument("VramArena: a layer of 0 bytes a tile");
    page_bytes += b + static_cast<long double>(sizeof(std::uint64_t) + sizeof(TileKey));
  }
  std::uint64_t slots = 0;
  for (const auto& L : levels_) {
    if (L.wx < 1 || L.wy < 1) throw std::invalid_argument("VramArena: empty window");
    level_base_.push_back(slots);
    std::int64_t tiles = 0;
    std::uint64_t level_slots = 0;
    if (__builtin_mul_overflow(L.wx, L.wy, &tiles) ||
        __builtin_mul_overflow(static_cast<std::uint64_t>(tiles), layer_bytes_.size(), &level_slots) ||
        __builtin_add_overflow(slots, level_slots, &slots))
      throw ArenaTooLarge(UINT64_MAX, host_limit);
  }
  const long double need = static_cast<long double>(slots / layer_bytes_.size()) * page_bytes;
  if (need > static_cast<long double>(host_limit))
    throw ArenaTooLarge(need >= 0x1p64L ? UINT64_MAX : static_cast<std::uint64_t>(need), host_limit);
  slot_offset_.resize(slots);
  std::uint64_t off = 0;
  for (std::uint64_t s = 0; s < slots; ++s) {
    slot_offset_[s] = off;
    off += layer_bytes_[s % layer_bytes_.size()];
  }
  bytes_ = off;
  owner_.assign(slots, TileKey{});
  for (auto& k : owner_) k.bits = kNone;
  // Touched up front, as a GPU allocation is made before streaming starts: no page faults mid-frame.
  mem_ = std::make_unique<std::uint8_t[]>(bytes_);
}

VramArena VramArena::for_clipmap(const ClipmapParams& p, std::vector<std::uint32_t> layer_bytes, std::uint64_t host_limit) {
  const Clipmap cm(p);
  std::vector<LevelWindow> levels;
  for (int l = 0; l < cm.num_levels(); ++l) {
    const Clipmap::Window w = cm.window(l);
    levels.push_back({w.w, w.h});
  }
  return VramArena(std::move(levels), std::move(layer_bytes), host_limit);
}

VramArena VramArena::for_pool(std::uint32_t slots, std::vector<std::uint32_t> layer_bytes, std::uint64_t host_limit) {
  VramArena a({LevelWindow{static_cast<std::int64_t>(slots), 1}}, std::move(layer_bytes), host_limit);
  a.pool_ = true;
  return a;
}

std::size_t VramArena::slot(TileKey key, std::int64_t pool_slot) const {
  if (key.layer() >= layer_bytes_.size())
    throw std::invalid_argument("VramArena: tile layer " + std::to_string(key.layer()) + " is outside the arena");
  if (pool_ != (pool_slot >= 0))
    throw std::invalid_argument(pool_ ? "VramArena: a pool arena needs the page's pool slot"
                                      : "VramArena: a window arena places tiles by key, not by pool slot");
  if (pool_) {
    if (pool_slot >= levels_[0].wx)
      throw std::invalid_argument("VramArena: pool slot " + std::to_string(pool_slot) + " is outside the pool of " +
                                  std::to_string(levels_[0].wx));
    return static_cast<std::size_t>(static_cast<std::uint64_t>(pool_slot) * layer_bytes_.size() + key.layer());
  }
  if (key.level() >= levels_.size())
    throw std::invalid_argument("VramArena: tile level " + std::to_string(key.level()) + " layer " +
                                std::to_string(key.layer()) + " is outside the arena");
  const LevelWindow& L = levels_[key.level()];
  const std::int64_t sx = key.x() % L.wx, sy = key.y() % L.wy;  // coordinates are >= 0
  return static_cast<std::size_t>(level_base_[key.level()] +
                                  static_cast<std::uint64_t>(sy * L.wx + sx) * layer_bytes_.size() + key.layer());
}

void VramArena::upload(const TileData& tile, std::int64_t pool_slot) {
  const std::size_t s = slot(tile.key, pool_slot);
  if (tile.bytes != layer_bytes_[tile.key.layer()] || !tile.texels)
    throw std::invalid_argument("VramArena: tile of " + std::to_string(tile.bytes) + " bytes for a slot of " +
                                std::to_string(layer_bytes_[tile.key.layer()]));
  const auto t0 = std::chrono::steady_clock::now();
  std::memcpy(mem_.get() + slot_offset_[s], tile.texels.get(), tile.bytes);
  stats_.copy_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
  if (owner_[s].bits != kNone && owner_[s] != tile.key) ++stats_.overwrites;
  owner_[s] = tile.key;
  ++stats_.uploads;
  stats_.bytes += tile.bytes;
}

std::span<const std::uint8_t> VramArena::peek(TileKey key, std::int64_t pool_slot) const {
  const std::size_t s = slot(key, pool_slot);
  if (owner_[s] != key) return {};
  return {mem_.get() + slot_offset_[s], layer_bytes_[key.layer()]};
}

}  // namespace vtsim
