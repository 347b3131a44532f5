#pragma once
// Tile identity: (layer, level, x, y) packed into 64 bits — layer 4 bits, level 6 bits, x and y
// 27 bits each (up to 2^27 tiles a side per level: a 2^34-texel texture at 128-texel tiles).
// Integral all the way: tile and texel coordinates are never floats (Unity Clipmap's float32 global
// UVs stop resolving texels near 2^23).
#include <cstdint>
#include <functional>

namespace vtsim {

struct TileKey {
  static constexpr int kLayerBits = 4, kLevelBits = 6, kCoordBits = 27;
  static constexpr std::uint32_t kMaxLayers = 1u << kLayerBits;
  static constexpr std::uint32_t kMaxLevels = 1u << kLevelBits;
  static constexpr std::int64_t kMaxCoord = (std::int64_t{1} << kCoordBits) - 1;

  std::uint64_t bits = 0;

  constexpr TileKey() = default;
  constexpr TileKey(std::uint32_t layer, std::uint32_t level, std::int64_t x, std::int64_t y)
      : bits((std::uint64_t{layer} << 60) | (std::uint64_t{level} << 54) |
             (static_cast<std::uint64_t>(x) << 27) | static_cast<std::uint64_t>(y)) {}

  constexpr std::uint32_t layer() const { return static_cast<std::uint32_t>(bits >> 60); }
  constexpr std::uint32_t level() const { return static_cast<std::uint32_t>((bits >> 54) & 63u); }
  constexpr std::int64_t x() const { return static_cast<std::int64_t>((bits >> 27) & kMaxCoord); }
  constexpr std::int64_t y() const { return static_cast<std::int64_t>(bits & kMaxCoord); }

  // Valid coordinates for packing (the caller checks before constructing).
  static constexpr bool fits(std::uint32_t layer, std::uint32_t level, std::int64_t x, std::int64_t y) {
    return layer < kMaxLayers && level < kMaxLevels && x >= 0 && y >= 0 && x <= kMaxCoord && y <= kMaxCoord;
  }

  friend constexpr bool operator==(TileKey a, TileKey b) { return a.bits == b.bits; }
  friend constexpr bool operator<(TileKey a, TileKey b) { return a.bits < b.bits; }
};

// A cheap, well-mixed hash (splitmix64 finaliser): packed keys of neighbouring tiles differ in
// low bits only, which identity hashing would cluster.
inline std::uint64_t mix64(std::uint64_t z) {
  z ^= z >> 30; z *= 0xbf58476d1ce4e5b9ULL;
  z ^= z >> 27; z *= 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

struct TileKeyHash {
  std::size_t operator()(TileKey k) const { return static_cast<std::size_t>(mix64(k.bits)); }
};

}  // namespace vtsim
