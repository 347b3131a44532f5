// Atlases (crazii 2017, docs/produced.md "Atlases (crazii 2017)"): mip-by-mip wrapped borders, the
// bleeding they prevent, the levels they cover, and the errors for bad brushes.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "core/error.h"
#include "stream/produce/atlas.h"
#include "stream/produce/compositor.h"

using namespace vtsim::produce;

namespace {

Rgba8 atlas_solid(int s, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  Rgba8 im;
  im.width = im.height = s;
  for (int i = 0; i < s * s; ++i) im.texels.insert(im.texels.end(), {r, g, b, 255});
  return im;
}

Rgba8 atlas_ramp(int s) {  // texel (x, y) = (x * 7 + y * 3) mod 256 in R, distinct per column
  Rgba8 im;
  im.width = im.height = s;
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x)
      im.texels.insert(im.texels.end(), {static_cast<std::uint8_t>((x * 7 + y * 3) & 255), static_cast<std::uint8_t>(x), static_cast<std::uint8_t>(y), 255});
  return im;
}

// Largest channel difference from `want` over a grid of samples across brush b at level m.
int atlas_bleed(const Atlas& a, int m, int b, bool inset, const std::uint8_t want[4]) {
  int worst = 0;
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 64; ++i) {
      std::uint8_t px[4];
      sample_bilinear(a, m, b, (i + 0.5) / 64.0 + 3.0, (j + 0.5) / 64.0 - 2.0, inset, px);
      for (int c = 0; c < 4; ++c) worst = std::max(worst, std::abs(px[c] - want[c]));
    }
  return worst;
}

}  // namespace

TEST_CASE("atlas: level m holds each brush's own box-filtered mip with a wrapped border") {
  const std::vector<Rgba8> brushes = {atlas_ramp(16), atlas_solid(16, 200, 10, 10), atlas_solid(16, 10, 200, 10)};
  const Atlas a = build_atlas(brushes, {}, {.cols = 2, .border = 4});
  CHECK(a.rows == 2);
  REQUIRE(a.levels.size() == 3);  // N_m = 4, 2, 1: the levels the border covers
  CHECK(a.levels[0].width == 2 * 24);
  CHECK(a.levels[2].border == 1);
  const std::vector<Rgba8> mips = brush_mips(brushes[0]);
  for (int m = 0; m < 3; ++m) {
    const AtlasLevel& lv = a.levels[static_cast<std::size_t>(m)];
    const int s = lv.brush_side;
    for (int y = -lv.border; y < s + lv.border; ++y)
      for (int x = -lv.border; x < s + lv.border; ++x) {
        const int wx = (x + s) % s, wy = (y + s) % s;
        const std::uint8_t* want = &mips[static_cast<std::size_t>(m)].texels[static_cast<std::size_t>(wy * s + wx) * 4];
        const std::uint8_t* got = lv.texel(a.cols, 0, x, y);
        CHECK(std::equal(want, want + 4, got));
      }
  }
  // Box filter, rounded half up: mip 1 texel (0, 0) of the ramp.
  CHECK(mips[1].texels[0] == static_cast<std::uint8_t>((0 + 7 + 3 + 10 + 2) >> 2));
  // constant_border keeps N at every level, down to 1 x 1.
  const Atlas c = build_atlas(brushes, {}, {.cols = 2, .border = 4, .constant_border = true});
  CHECK(c.levels.size() == 5);
  CHECK(c.levels[4].border == 4);
}

TEST_CASE("atlas: without borders a neighbouring cell bleeds in, more at coarse levels, with borders none") {
  const std::vector<Rgba8> brushes = {atlas_solid(32, 250, 0, 0), atlas_solid(32, 0, 250, 0), atlas_solid(32, 0, 0, 250),
                                      atlas_solid(32, 250, 250, 0)};
  const std::uint8_t red[4] = {250, 0, 0, 255};
  const Atlas bare = build_atlas(brushes, {}, {.cols = 2, .border = 0});
  REQUIRE(bare.levels.size() == 6);
  int prev = 0;
  for (int m = 0; m < 6; ++m) {
    const int bleed = atlas_bleed(bare, m, 0, false, red);
    CHECK_MESSAGE(bleed > 0, "level " << m);  // green from the cell to the right, blue below
    CHECK(bleed >= prev);
    prev = bleed;
    CHECK(atlas_bleed(bare, m, 0, true, red) == 0);  // the half-texel inset alone stops it
  }
  const Atlas bordered = build_atlas(brushes, {}, {.cols = 2, .border = 4});
  REQUIRE(bordered.levels.size() == 3);
  for (int m = 0; m < 3; ++m) CHECK(atlas_bleed(bordered, m, 0, false, red) == 0);
}

TEST_CASE("atlas: frac() derivatives select the coarsest level at the wrap, unwrapped ones do not") {
  const int s = 256;
  const double mpt = 0.01, period = 1.0;  // 100 output texels a repeat: footprint 2.56 brush texels
  int coarse_frac = 0, coarse_unwrapped = 0;
  for (int i = 0; i < 1000; ++i) {
    const double u0 = (i * mpt) / period, u1 = ((i + 1) * mpt) / period;
    const double frac_d = (u1 - std::floor(u1)) - (u0 - std::floor(u0));
    if (lod_from_derivative(frac_d, s) > 7.0) ++coarse_frac;  // log2(256 * ~1) = 8: the 1 x 1 level's neighbourhood
    if (lod_from_derivative(u1 - u0, s) > 7.0) ++coarse_unwrapped;
  }
  CHECK(coarse_frac >= 9);  // one seam per repeat
  CHECK(coarse_unwrapped == 0);
  const Atlas a = build_atlas({atlas_solid(s, 1, 2, 3)}, {}, {.cols = 1, .border = 4});
  CHECK(select_level(a, mpt, period) == 1);  // log2(2.56) = 1.36 -> 1
  CHECK(select_level(a, 1.0, period) == a.max_level());  // clamped to the levels the border covers
}

TEST_CASE("atlas: the transition cross-fades the edges so the wrap has no hard seam") {
  Rgba8 b = atlas_ramp(64);  // R jumps from 63*7 & 255 to 0 across the wrap
  const int before = std::abs(b.texels[0] - b.texels[63 * 4]);
  apply_transition(b, 4);
  const int after = std::abs(b.texels[0] - b.texels[63 * 4]);
  CHECK(after * 4 < before);
  CHECK(b.texels[(10 * 64 + 10) * 4] == atlas_ramp(64).texels[(10 * 64 + 10) * 4]);  // the inside is untouched
}

TEST_CASE("atlas: bad brushes and fields are refused naming the file or field") {
  const auto err = [](const std::vector<Rgba8>& b, const AtlasParams& p) {
    try {
      build_atlas(b, {"a.png", "b.png", "c.png"}, p);
    } catch (const vtsim::InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK(err({atlas_solid(12, 0, 0, 0)}, {}).find("a.png: brush side 12 is not a power of two") == 0);
  CHECK(err({atlas_solid(16, 0, 0, 0), atlas_solid(32, 0, 0, 0)}, {}).find("b.png: brush is 32x32 but a.png is 16x16") == 0);
  CHECK(err({atlas_solid(16, 0, 0, 0), atlas_solid(16, 0, 0, 0), atlas_solid(16, 0, 0, 0)}, {.cols = 1, .rows = 2}).find("rows: 3 brushes") == 0);
  CHECK(err({atlas_solid(16, 0, 0, 0)}, {.border = -1}).find("border: -1") == 0);
  // 8 cells of 2048 + 2 x 4 texels = 16,448 > 16,384 (small brushes: the check is on sizes, not memory).
  CHECK(err({atlas_solid(2048, 0, 0, 0)}, {.cols = 8}).find("cols: an atlas of 8 x 1 cells") == 0);
}
