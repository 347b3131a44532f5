#include <doctest/doctest.h>

#include "core/tile_key.h"

using vtsim::TileKey;

TEST_CASE("TileKey packs and unpacks every field at its extremes") {
  const std::int64_t m = TileKey::kMaxCoord;
  for (std::uint32_t layer : {0u, 1u, 15u})
    for (std::uint32_t level : {0u, 7u, 63u})
      for (std::int64_t x : {std::int64_t{0}, std::int64_t{1}, m - 1, m})
        for (std::int64_t y : {std::int64_t{0}, std::int64_t{12345}, m}) {
          REQUIRE(TileKey::fits(layer, level, x, y));
          TileKey k(layer, level, x, y);
          CHECK(k.layer() == layer);
          CHECK(k.level() == level);
          CHECK(k.x() == x);
          CHECK(k.y() == y);
        }
  CHECK_FALSE(TileKey::fits(16, 0, 0, 0));
  CHECK_FALSE(TileKey::fits(0, 64, 0, 0));
  CHECK_FALSE(TileKey::fits(0, 0, -1, 0));
  CHECK_FALSE(TileKey::fits(0, 0, 0, m + 1));
}

TEST_CASE("TileKey order is by layer, then level, then x, then y") {
  CHECK(TileKey(0, 5, 9, 9) < TileKey(1, 0, 0, 0));
  CHECK(TileKey(0, 1, 9, 9) < TileKey(0, 2, 0, 0));
  CHECK(TileKey(0, 1, 1, 9) < TileKey(0, 1, 2, 0));
  CHECK(TileKey(0, 1, 1, 1) < TileKey(0, 1, 1, 2));
}
