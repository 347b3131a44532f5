// Procedural masks from slope and height (docs/produced.md "Procedural masks"): exact weights on
// a flat plane, a 45° ramp and a height transition; bad rules refused naming the field.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include "core/error.h"
#include "stream/produce/atlas.h"
#include "stream/produce/compositor.h"
#include "stream/produce/masks.h"

using namespace vtsim::produce;

namespace {

// nx x ny posts 1 m apart from (0, 0) with z = a x + b y + c.
std::vector<float> masks_plane(int nx, int ny, double a, double b, double c) {
  std::vector<float> z;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) z.push_back(static_cast<float>(a * i + b * j + c));
  return z;
}

}  // namespace

TEST_CASE("masks: a flat plane gives the flat rule's layer 255 everywhere") {
  const std::vector<float> z = masks_plane(9, 9, 0, 0, 5);
  const HeightGrid g{9, 9, 1.0, 0.0, 0.0, z.data()};
  std::vector<LayerRule> rules(2);
  rules[0].slope_hi_deg = 10;     // flat ground
  rules[1].slope_lo_deg = 30;     // cliffs
  rules[1].slope_soft_deg = 10;
  const ProceduralMasks pm = procedural_masks(g, rules, 8, 8, 0.0, 0.0, 1.0);
  REQUIRE(pm.rgba.size() == 1);
  for (std::size_t t = 0; t < 64; ++t) {
    CHECK(pm.rgba[0][t * 4 + 0] == 255);
    CHECK(pm.rgba[0][t * 4 + 1] == 0);
    CHECK(pm.rgba[0][t * 4 + 2] == 0);  // no rule: 0
  }
  // Through the compositor: the tile is brush 0's colour exactly.
  Rgba8 red, blue;
  red.width = red.height = blue.width = blue.height = 8;
  for (int i = 0; i < 64; ++i) red.texels.insert(red.texels.end(), {200, 10, 20, 255}), blue.texels.insert(blue.texels.end(), {0, 0, 250, 255});
  const Atlas at = build_atlas({red, blue}, {}, {.cols = 2, .border = 2});
  const BrushLayer layers[2] = {{0, 1.0}, {1, 1.0}};
  const WeightMask wm = pm.mask(0);
  CompositeJob job;
  job.atlas = &at;
  job.layers = layers;
  job.masks = {&wm, 1};
  job.origin_x_m = 1.0;
  job.origin_y_m = 1.0;
  job.m_per_texel = 0.125;
  job.tile = 16;
  std::vector<std::uint8_t> out(16 * 16 * 4);
  Compositor().compose(job, out.data());
  for (std::size_t t = 0; t < 256; ++t) {
    CHECK(out[t * 4 + 0] == 200);
    CHECK(out[t * 4 + 2] == 20);
  }
}

TEST_CASE("masks: a 45 degree ramp selects the slope layer, exactly 45 degrees") {
  const std::vector<float> z = masks_plane(9, 9, 1.0, 0, 0);  // z = x
  const HeightGrid g{9, 9, 1.0, 0.0, 0.0, z.data()};
  CHECK(grid_slope_deg(g, 3.3, 4.1) == doctest::Approx(45.0).epsilon(1e-12));
  CHECK(grid_slope_deg(g, 0.0, 0.0) == doctest::Approx(45.0).epsilon(1e-12));  // at the edge too
  CHECK(grid_height(g, 3.25, 7.5) == doctest::Approx(3.25));
  std::vector<LayerRule> rules(2);
  rules[0].slope_hi_deg = 10;
  rules[1].slope_lo_deg = 40;
  rules[1].slope_hi_deg = 50;
  const ProceduralMasks pm = procedural_masks(g, rules, 8, 8, 0.0, 0.0, 1.0);
  for (std::size_t t = 0; t < 64; ++t) {
    CHECK(pm.rgba[0][t * 4 + 0] == 0);
    CHECK(pm.rgba[0][t * 4 + 1] == 255);
  }
  // A 30 degree slope against [40, 50] soft 40: factor 1 - 10/40 = 0.75 -> 191.25 -> 191.
  const std::vector<float> z30 = masks_plane(9, 9, std::tan(30.0 * 3.14159265358979323846 / 180), 0, 0);
  const HeightGrid g30{9, 9, 1.0, 0.0, 0.0, z30.data()};
  rules[1].slope_soft_deg = 40;
  CHECK(procedural_masks(g30, rules, 4, 4, 0.0, 0.0, 1.0).rgba[0][1] == 191);
}

TEST_CASE("masks: a height transition is as wide as the soft width over the gradient") {
  // z = 0.1 x over x in [0, 100] m: layer 0 up to 5 m with a 2 m soft edge fades out between
  // x = 50 and 70 m; layer 1 from 5 m (hard edge) takes over at x = 50 m.
  const std::vector<float> z = masks_plane(101, 2, 0.1, 0, 0);
  const HeightGrid g{101, 2, 1.0, 0.0, 0.0, z.data()};
  std::vector<LayerRule> rules(2);
  rules[0].height_hi_m = 5;
  rules[0].height_soft_m = 2;
  rules[1].height_lo_m = 5;
  const ProceduralMasks pm = procedural_masks(g, rules, 100, 1, 0.0, 0.0, 1.0);
  int partial = 0, first = -1;
  for (int x = 0; x < 100; ++x) {
    const int w = pm.rgba[0][static_cast<std::size_t>(x) * 4];
    if (w > 0 && w < 255) {
      ++partial;
      if (first < 0) first = x;
    }
    CHECK(pm.rgba[0][static_cast<std::size_t>(x) * 4 + 1] == (x >= 50 ? 255 : 0));
  }
  CHECK(partial == 20);  // 2 m / 0.1 m per m = 20 m of 1 m texels
  CHECK(first == 50);
  CHECK(pm.rgba[0][60 * 4] == 121);  // centre 60.5 m: z = 6.05 m, 1 - 1.05 / 2 = 0.475 -> 121
  CHECK(pm.rgba[0][49 * 4] == 255);
  CHECK(pm.rgba[0][70 * 4] == 0);
}

TEST_CASE("masks: bad grids and rules are refused naming the field") {
  const std::vector<float> z = masks_plane(2, 2, 0, 0, 0);
  const HeightGrid g{2, 2, 1.0, 0.0, 0.0, z.data()};
  std::vector<LayerRule> rules(1);
  rules[0].height_lo_m = 3;
  rules[0].height_hi_m = 1;
  CHECK_THROWS_WITH_AS(procedural_masks(g, rules, 2, 2, 0, 0, 1), doctest::Contains("rules[0].height: lo 3 > hi 1"), vtsim::InputError);
  rules[0] = {};
  rules[0].slope_soft_deg = -1;
  CHECK_THROWS_WITH_AS(procedural_masks(g, rules, 2, 2, 0, 0, 1), doctest::Contains("rules[0]"), vtsim::InputError);
  CHECK_THROWS_WITH_AS(procedural_masks(g, std::vector<LayerRule>(17), 2, 2, 0, 0, 1), doctest::Contains("rules: 17 rules"), vtsim::InputError);
  const HeightGrid one{1, 2, 1.0, 0.0, 0.0, z.data()};
  CHECK_THROWS_WITH_AS(procedural_masks(one, std::vector<LayerRule>(1), 2, 2, 0, 0, 1), doctest::Contains("heightfield"), vtsim::InputError);
  CHECK_THROWS_WITH_AS(procedural_masks(g, std::vector<LayerRule>(1), 0, 2, 0, 0, 1), doctest::Contains("mask"), vtsim::InputError);
}
