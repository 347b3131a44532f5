#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "cache/clipmap.h"

using namespace vtsim;

namespace {

ClipmapParams small(std::int64_t w = 8192, std::int64_t h = 8192) {
  ClipmapParams p;
  p.extent = {w, h};
  p.tile_size = 128;
  p.clipsize = 1024;
  p.layers = 1;
  p.update_threshold_tiles = 0.5;
  return p;
}

// Places the windows for ground texel (gu, gv) and makes every needed tile resident.
void settle(Clipmap& cm, std::int64_t gu, std::int64_t gv, int finest = 0) {
  cm.update_windows(gu, gv, finest);
  std::vector<Need> needs;
  cm.emit_needs(finest, [](int, std::int64_t, std::int64_t) { return 0u; }, needs);
  for (const Need& n : needs) REQUIRE(cm.commit(n.key));
}

bool window_contains(const Clipmap& cm, int level, std::int64_t tx, std::int64_t ty) {
  const auto w = cm.window(level);
  return tx >= w.x0 && tx < w.x0 + w.w && ty >= w.y0 && ty < w.y0 + w.h;
}

}  // namespace

TEST_CASE("clipmap: stack and pyramid split at the clipsize") {
  Clipmap cm(small());
  CHECK(cm.num_levels() == 14);          // 8192 .. 1
  CHECK(cm.first_pyramid_level() == 3);  // 8192, 4096, 2048 exceed N = 1024
  CHECK(cm.window_tiles() == 8);
  Clipmap odd(small(1000, 600));         // no stack at all: 1000 <= 1024
  CHECK(odd.first_pyramid_level() == 0);
  CHECK(odd.num_levels() == 11);         // 1000, 500, 250, 125, 63, 32, 16, 8, 4, 2, 1
}

TEST_CASE("clipmap: windows are centred on the camera and clamped inside the level") {
  Clipmap cm(small());
  settle(cm, 4096 + 10, 4096 + 10);
  // Level 0: camera tile 32 -> window [28, 36).
  CHECK(cm.window(0).x0 == 28);
  CHECK(cm.window(1).x0 == 16 - 4);
  CHECK(cm.window(2).x0 == 4);  // 2048 texels = 16 tiles; camera tile 8 -> [4, 12)
}

TEST_CASE("clipmap: a camera outside the texture pulls windows to the nearest edge") {
  Clipmap cm(small());
  settle(cm, -1'000'000, 20'000'000);
  CHECK(cm.window(0).x0 == 0);
  CHECK(cm.window(0).y0 == 64 - 8);
  settle(cm, 8191, 0);
  CHECK(cm.window(0).x0 == 64 - 8);
  CHECK(cm.window(0).y0 == 0);
}

TEST_CASE("clipmap: toroidal slots are right for huge coordinates (2^34 texels a side)") {
  ClipmapParams p = small(std::int64_t{1} << 34, std::int64_t{1} << 34);
  Clipmap cm(p);
  CHECK(cm.num_levels() == 35);
  const std::int64_t g = (std::int64_t{1} << 33) + 12345;
  settle(cm, g, g);
  CHECK(cm.resident_level(g, g, 0) == 0);
  CHECK(cm.resident_level(g + 4 * 128, g, 0) > 0);  // outside level 0's 8-tile window
  // Walk one tile at a time for 20 tiles: each step overwrites exactly the slots of the column
  // that left, and the tile under the camera stays resident at level 0.
  Clipmap::Stats before = cm.stats();
  for (int i = 1; i <= 20; ++i) {
    settle(cm, g + i * 128, g);
    CHECK(cm.resident_level(g + i * 128, g, 0) == 0);
    CHECK(cm.resident(TileKey(0, 0, (g + i * 128) / 128, g / 128)));
  }
  CHECK(cm.stats().vram_evictions - before.vram_evictions >= 20 * 8);
}

TEST_CASE("clipmap: property — after settling anywhere, level l is valid exactly inside its window") {
  std::mt19937_64 rng(2024);
  ClipmapParams p = small(100'000, 70'001);  // not powers of two
  for (int trial = 0; trial < 40; ++trial) {
    Clipmap cm(p);
    std::uniform_int_distribution<std::int64_t> pos(-50'000, 150'000);
    const std::int64_t gu = pos(rng), gv = pos(rng);
    settle(cm, gu, gv);
    for (int probe = 0; probe < 200; ++probe) {
      std::uniform_int_distribution<std::int64_t> U(0, p.extent.width - 1), V(0, p.extent.height - 1);
      const std::int64_t u = U(rng), v = V(rng);
      const int r = cm.resident_level(u, v, 0);
      REQUIRE(r < cm.num_levels());  // something always covers: the pyramid
      // r is the finest level whose window holds the 3×3 footprint (margin 1, clamped at edges).
      for (int l = 0; l <= r; ++l) {
        const std::int64_t ul = u >> l, vl = v >> l;
        const std::int64_t lw = (p.extent.width + (std::int64_t{1} << l) - 1) >> l;
        const std::int64_t lh = (p.extent.height + (std::int64_t{1} << l) - 1) >> l;
        const std::int64_t x0 = std::max<std::int64_t>(0, ul - 1) / 128, x1 = std::min(lw - 1, ul + 1) / 128;
        const std::int64_t y0 = std::max<std::int64_t>(0, vl - 1) / 128, y1 = std::min(lh - 1, vl + 1) / 128;
        const bool inside = window_contains(cm, l, x0, y0) && window_contains(cm, l, x1, y1);
        CHECK(inside == (l == r));
      }
    }
  }
}

TEST_CASE("clipmap: update threshold hysteresis stops ping-pong across a tile edge") {
  // Boundary between tiles 32 and 33 of level 0 that is not a tile boundary of levels 1 and 2.
  const std::int64_t edge = 33 * 128;
  for (double thr : {0.0, 0.5}) {
    ClipmapParams p = small();
    p.update_threshold_tiles = thr;
    Clipmap cm(p);
    settle(cm, edge - 10, 4096);
    const auto moves0 = cm.stats().window_moves;
    for (int i = 0; i < 10; ++i) {
      settle(cm, edge + 20, 4096);
      settle(cm, edge - 20, 4096);
    }
    const auto moves = cm.stats().window_moves - moves0;
    if (thr == 0.0) CHECK(moves == 20);  // every crossing recentres level 0
    else CHECK(moves == 0);              // 20 texels < T/2 + 0.5 T beyond the centre tile
  }
  // The threshold boundary itself: centre tile 32 (texels [4096, 4224), centre 4160); with
  // threshold 0.5 (64 texels) the window moves at d >= 64 + 64, i.e. at texel 4288, not 4287.
  ClipmapParams p = small();
  Clipmap cm(p);
  settle(cm, 4160, 4160);
  const auto x0 = cm.window(0).x0;
  settle(cm, 4287, 4160);
  CHECK(cm.window(0).x0 == x0);
  settle(cm, 4288, 4160);
  CHECK(cm.window(0).x0 == x0 + 1);
}

TEST_CASE("clipmap: level selection uses the finest valid level even when finer levels commit first") {
  Clipmap cm(small());
  cm.update_windows(4096, 4096, 0);
  std::vector<Need> needs;
  cm.emit_needs(0, [](int, std::int64_t, std::int64_t) { return 0u; }, needs);
  // Commit level 0 only: Unity Clipmap's shader counted containing layers and would pick a wrong level.
  for (const Need& n : needs)
    if (n.key.level() == 0) cm.commit(n.key);
  CHECK(cm.resident_level(4096, 4096, 0) == 0);
  CHECK(cm.resident_level(4096, 4096, 1) == cm.num_levels());  // nothing coarser is resident yet
  CHECK(cm.resident_level(4096 + 2000, 4096, 0) == cm.num_levels());
  for (const Need& n : needs)
    if (n.key.level() == 2) cm.commit(n.key);
  CHECK(cm.resident_level(4096, 4096, 0) == 0);                 // finer still wins where valid
  CHECK(cm.resident_level(4096, 4096, 1) == 2);                 // level 1 missing: next valid
  CHECK(cm.resident_level(4096 + 2000, 4096, 0) == 2);          // outside level 0's window
  cm.set_clamp(2);
  CHECK(cm.resident_level(4096, 4096, 0) == 2);                 // MaxTextureLOD applies to sampling
}

TEST_CASE("clipmap: the filter margin and the invalid border exclude edge texels") {
  ClipmapParams p = small();
  Clipmap cm(p);
  settle(cm, 4096, 4096);
  const auto w = cm.window(0);  // [28, 36) tiles
  const std::int64_t first = w.x0 * 128, last = (w.x0 + w.w) * 128 - 1;
  CHECK(cm.resident_level(first + 1, 4096, 0) == 0);
  CHECK(cm.resident_level(first, 4096, 0) > 0);  // its left neighbour texel is outside
  CHECK(cm.resident_level(last, 4096, 0) > 0);
  CHECK(cm.resident_level(last - 1, 4096, 0) == 0);

  p.invalid_border_tiles = 1;
  Clipmap cb(p);
  settle(cb, 4096, 4096);
  CHECK(cb.resident_level(first + 128 + 1, 4096, 0) == 0);  // second tile: valid
  CHECK(cb.resident_level(first + 64, 4096, 0) > 0);        // edge tile: in the invalid border
  // At the texture's edge the window does not move: no invalid border there.
  settle(cb, 10, 10);
  CHECK(cb.resident_level(10, 10, 0) == 0);
}

TEST_CASE("clipmap: every level, the coarsest stack level included, follows the camera from any start") {
  const std::int64_t starts[][2] = {{0, 0}, {8191, 8191}, {-5000, 3000}, {4096, 4096}, {9'000'000, -9'000'000}};
  for (const auto& a : starts)
    for (const auto& b : starts) {
      Clipmap cm(small());
      settle(cm, a[0], a[1]);
      settle(cm, b[0], b[1]);
      for (int l = 0; l < cm.first_pyramid_level(); ++l) {
        const std::int64_t lt = (8192 >> l) / 128;
        const std::int64_t tx = std::clamp<std::int64_t>((b[0] >> l) / 128 - (b[0] < 0), 0, lt - 1);
        const std::int64_t ty = std::clamp<std::int64_t>((b[1] >> l) / 128 - (b[1] < 0), 0, lt - 1);
        CHECK(window_contains(cm, l, tx, ty));
        CHECK(cm.level_complete(l));
      }
      for (std::int64_t u = 0; u < 8192; u += 511)
        for (std::int64_t v = 0; v < 8192; v += 511) CHECK(cm.resident_level(u, v, 0) <= cm.first_pyramid_level());
    }
}

TEST_CASE("clipmap: levels finer than any sample needs are not updated") {
  Clipmap cm(small());
  settle(cm, 4096, 4096, 0);
  const auto w0 = cm.window(0), w1 = cm.window(1);
  settle(cm, 7000, 7000, 1);  // nothing on screen wants level 0
  CHECK(cm.window(0).x0 == w0.x0);
  CHECK(cm.window(1).x0 != w1.x0);
}

TEST_CASE("clipmap: missing bytes count the band that enters when the window moves") {
  Clipmap cm(small());
  settle(cm, 4160, 4160);
  std::vector<std::uint64_t> missing;
  cm.missing_bytes_by_level(4160, 4160, 0, 100, missing);
  for (auto m : missing) CHECK(m == 0);
  cm.missing_bytes_by_level(4160 + 127, 4160, 0, 100, missing);  // within the threshold: no move
  CHECK(missing[0] == 0);
  cm.missing_bytes_by_level(4160 + 256, 4160, 0, 100, missing);  // two tiles east: level 0 moves by 2
  CHECK(missing[0] == 2 * 8 * 100);
  CHECK(missing[1] == 0);  // level 1: 4416 >> 1 = 2208 is within its threshold
}

TEST_CASE("clipmap memory: the Yao 2007 §2-3 formula 4^m (n - m + 4/3) - 1/3, and the full mip chain") {
  for (int n = 9; n <= 26; ++n)
    for (int m = 9; m <= 11 && m <= n; ++m) {
      const ClipmapMemory mem = clipmap_memory({std::int64_t{1} << n, std::int64_t{1} << n}, 128, 1 << m);
      const long double expect = std::pow(4.0L, m) * (n - m + 4.0L / 3.0L) - 1.0L / 3.0L;
      CHECK(static_cast<long long>(mem.stack_texels + mem.pyramid_texels) == std::llroundl(expect));
      const long double full = (std::pow(4.0L, n + 1) - 1.0L) / 3.0L;
      CHECK(static_cast<long double>(mem.full_mip_texels) == full);
    }
  // Non-power-of-two: windows are whole tiles, pyramid levels their true size.
  const ClipmapMemory odd = clipmap_memory({100'000, 70'001}, 128, 1024);
  CHECK(odd.stack_levels == 7);  // 100000 .. 1563 exceed 1024
  CHECK(odd.stack_texels == 7u * 1024u * 1024u);
}

TEST_CASE("clipmap: the fingerprint follows the state lookups read, not the order that built it") {
  Clipmap a(small()), b(small());
  ResidencyFingerprint fa, fb;
  REQUIRE(a.fingerprint(fa));
  REQUIRE(b.fingerprint(fb));
  CHECK(fa == fb);
  a.update_windows(4096, 4096, 0);
  b.update_windows(4096, 4096, 0);
  std::vector<Need> needs;
  a.emit_needs(0, [](int, std::int64_t, std::int64_t) { return 0u; }, needs);
  REQUIRE(needs.size() > 4);
  // The same tiles committed in opposite orders: the same state, the same fingerprint.
  for (const Need& n : needs) REQUIRE(a.commit(n.key));
  for (auto it = needs.rbegin(); it != needs.rend(); ++it) REQUIRE(b.commit(it->key));
  a.fingerprint(fa);
  b.fingerprint(fb);
  CHECK(fa == fb);
  // Each part of the state changes it: the clamp, a window, parameters.
  b.set_clamp(2);
  b.fingerprint(fb);
  CHECK_FALSE(fa == fb);
  b.set_clamp(0);
  b.fingerprint(fb);
  CHECK(fa == fb);
  b.update_windows(4096 + 4 * 128, 4096, 0);
  b.fingerprint(fb);
  CHECK_FALSE(fa == fb);
  ClipmapParams p = small();
  p.filter_margin_texels = 2;
  Clipmap c(p);
  ResidencyFingerprint fc;
  c.fingerprint(fc);
  Clipmap d(small());
  d.fingerprint(fb);
  CHECK_FALSE(fc == fb);
  // Sampled flags are not state the lookups read: marking leaves the fingerprint.
  a.set_mark_sampled(true);
  CHECK(a.resident_level(4096, 4096, 0) == 0);
  ResidencyFingerprint fa2;
  a.fingerprint(fa2);
  CHECK(fa2 == fa);
}

TEST_CASE("clipmap: recorded marks, applied to a clipmap in the same state, leave the same sampled tiles") {
  Clipmap a(small()), b(small());
  settle(a, 4096, 4096);
  settle(b, 4096, 4096);
  std::vector<ViewSample> s;
  for (std::int64_t u = 3000; u < 5200; u += 97) s.push_back(ViewSample{u, 4100, 0.0f});
  std::vector<std::int8_t> out(s.size());
  std::vector<std::uint64_t> marks;
  a.set_mark_sampled(true);
  a.record_marks(&marks);
  a.resident_levels(s.data(), s.size(), out.data());
  a.record_marks(nullptr);
  REQUIRE(!marks.empty());
  std::vector<std::uint64_t> sorted = marks;
  std::sort(sorted.begin(), sorted.end());
  CHECK(std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end());  // each slot once
  CHECK(b.resident_unsampled() > a.resident_unsampled());
  b.apply_marks(marks);
  CHECK(b.resident_unsampled() == a.resident_unsampled());
  CHECK_THROWS_AS(b.apply_marks({std::uint64_t{99} << 40}), std::invalid_argument);
}
