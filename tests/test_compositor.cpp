// The compositor (docs/produced.md "The compositor"): exact fixed-point blends, weights from masks,
// the work it counts, bad jobs.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdlib>
#include <string>
#include <vector>

#include "core/error.h"
#include "stream/produce/atlas.h"
#include "stream/produce/compositor.h"

using namespace vtsim::produce;

namespace {

Rgba8 comp_solid(int s, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  Rgba8 im;
  im.width = im.height = s;
  for (int i = 0; i < s * s; ++i) im.texels.insert(im.texels.end(), {r, g, b, 255});
  return im;
}

}  // namespace

TEST_CASE("compositor: blend_rgba8 rounds sum w c / 2^14 half up") {
  const std::vector<std::uint8_t> a = {255, 0, 100, 1}, b = {0, 255, 101, 2};
  const std::vector<std::uint16_t> wa = {kWeightOne / 2}, wb = {kWeightOne / 2};
  const std::uint8_t* l[2] = {a.data(), b.data()};
  const std::uint16_t* w[2] = {wa.data(), wb.data()};
  std::uint8_t out[4];
  blend_rgba8(l, w, 2, 1, out);
  CHECK(out[0] == 128);  // 127.5 -> 128
  CHECK(out[1] == 128);
  CHECK(out[2] == 101);  // 100.5 -> 101
  CHECK(out[3] == 2);    // 1.5 -> 2
}

TEST_CASE("compositor: a two-layer mask blend is exact and deterministic, and count_work matches it") {
  const Atlas at = build_atlas({comp_solid(16, 200, 0, 0), comp_solid(16, 0, 100, 0), comp_solid(16, 0, 0, 50)}, {}, {.cols = 2, .border = 2});
  // Mask 2 x 1 texels over [0, 2) m: left all layer 0, right 3/4 layer 0 + 1/4 layer 1; layer 2 unused.
  const std::vector<std::uint8_t> mask = {255, 0, 0, 0, 192, 64, 0, 0};
  const WeightMask wm{2, 1, mask.data(), 0.0, 0.0, 1.0};
  const BrushLayer layers[3] = {{0, 1.0}, {1, 1.0}, {2, 1.0}};
  CompositeJob job;
  job.atlas = &at;
  job.layers = layers;
  job.masks = {&wm, 1};
  job.origin_x_m = 0.0;
  job.origin_y_m = 0.0;
  job.m_per_texel = 2.0 / 8;
  job.tile = 8;
  job.border = 1;
  std::vector<std::uint8_t> out(10 * 10 * 4), again(out.size());
  Compositor c;
  c.compose(job, out.data());
  c.compose(job, again.data());
  CHECK(out == again);
  // Texel x = 0 (border, world -0.125 m): clamped to mask texel 0 -> pure layer 0.
  CHECK(out[0] == 200);
  CHECK(out[1] == 0);
  // Texel x = 9 (border, world 2.125 m): clamped to mask texel 1 -> 0.75 * 200, 0.25 * 100.
  CHECK(out[9 * 4 + 0] == 150);
  CHECK(out[9 * 4 + 1] == 25);
  CHECK(out[9 * 4 + 3] == 255);
  const vtsim::ProduceWork w = count_work(job);
  CHECK(w.texels == 100);
  CHECK(w.layers == 2);
  CHECK(w.decals == 0);
  const Decal d[2] = {{0.5, 0.5, 1.0, 1.0}, {5.0, 5.0, 6.0, 6.0}};
  job.decals = d;
  CHECK(count_work(job).decals == 1);
}

TEST_CASE("compositor: bad jobs are refused naming the field") {
  const Atlas at = build_atlas({comp_solid(16, 1, 1, 1)}, {}, {.cols = 1});
  const BrushLayer layers[1] = {{3, 1.0}};
  const std::vector<std::uint8_t> mask(4, 255);
  const WeightMask wm{1, 1, mask.data(), 0, 0, 1};
  CompositeJob job;
  job.atlas = &at;
  job.layers = layers;
  job.masks = {&wm, 1};
  std::vector<std::uint8_t> out(128 * 128 * 4);
  Compositor c;
  CHECK_THROWS_WITH_AS(c.compose(job, out.data()), doctest::Contains("layers: cell 3 (atlas has 1)"), vtsim::InputError);
  job.masks = {};
  CHECK_THROWS_WITH_AS(c.compose(job, out.data()), doctest::Contains("masks: 0 masks weight 1 layers"), vtsim::InputError);
}

TEST_CASE("compositor: compose is within 1 of the exact double-precision tile") {
  // Brushes whose neighbouring texels differ by < 32 per channel (docs/produced.md's bound), a
  // mask with smooth gradients over three layers, periods that select levels 0 and 1.
  std::vector<Rgba8> brushes;
  for (int b = 0; b < 3; ++b) {
    Rgba8 im;
    im.width = im.height = 32;
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x)
        for (int c = 0; c < 4; ++c) im.texels.push_back(static_cast<std::uint8_t>(60 * b + 40 * c / 3 + (x * 7 + y * 13 + c * 5) % 31));
    brushes.push_back(std::move(im));
  }
  const Atlas at = build_atlas(brushes, {}, {.cols = 2, .border = 2});
  std::vector<std::uint8_t> mask;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) mask.insert(mask.end(), {static_cast<std::uint8_t>(30 * x), static_cast<std::uint8_t>(30 * y), static_cast<std::uint8_t>(255 - 15 * (x + y)), 0});
  const WeightMask wm{8, 8, mask.data(), 0.0, 0.0, 1.0};
  const BrushLayer layers[3] = {{0, 1.3}, {1, 0.9}, {2, 2.1}};
  CompositeJob job;
  job.atlas = &at;
  job.layers = layers;
  job.masks = {&wm, 1};
  job.origin_x_m = 0.7;
  job.origin_y_m = 1.1;
  job.m_per_texel = 6.0 / 64;
  job.tile = 64;
  job.border = 2;
  std::vector<std::uint8_t> out(68 * 68 * 4), exact(out.size());
  Compositor().compose(job, out.data());
  compose_exact(job, exact.data());
  int worst = 0, differ = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    worst = std::max(worst, std::abs(out[i] - exact[i]));
    differ += out[i] != exact[i];
  }
  CHECK(worst == 1);  // rounding shows somewhere, never more than 1
  CHECK(differ > 0);
}

TEST_CASE("compositor: every path gives the reference loop's bytes - borders 0 2 4, constant border, 1 to 16 layers, magnified and minified") {
  // Noisy brushes (0 <-> 255 neighbours: the taps' weights all show), masks with zero corners (the
  // zero-sum rule) and noise, tiles whose brush steps wrap, clamp at the coarsest level or magnify.
  const auto noise = [](std::uint64_t x) {
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return static_cast<std::uint8_t>((x ^ (x >> 31)) & 255);
  };
  std::vector<Rgba8> brushes;
  for (int b = 0; b < 16; ++b) {
    Rgba8 im;
    im.width = im.height = 32;
    for (std::uint64_t i = 0; i < 32 * 32 * 4; ++i) im.texels.push_back(noise(i * 131 + static_cast<std::uint64_t>(b) * 7919 + 1));
    brushes.push_back(std::move(im));
  }
  struct Case {
    int border;
    bool constant;
    int layers;
    double m_per_texel, period0;
    int tile, tile_border;
  };
  const Case cases[] = {{0, false, 3, 0.01, 1.0, 29, 0},  {2, false, 1, 0.05, 0.7, 16, 1},  {4, false, 8, 0.013, 0.9, 64, 4},
                        {4, true, 16, 0.37, 1.1, 40, 2},  {2, false, 16, 2.5, 0.6, 33, 3},  {0, false, 5, 0.2, 3.3, 50, 4}};
  for (const Case& cs : cases) {
    CAPTURE(cs.border);
    CAPTURE(cs.layers);
    CAPTURE(cs.m_per_texel);
    const Atlas at = build_atlas(brushes, {}, {.cols = 4, .border = cs.border, .constant_border = cs.constant});
    std::vector<std::vector<std::uint8_t>> mask_px(4);
    std::vector<WeightMask> masks;
    for (std::size_t mi = 0; mi < 4; ++mi) {
      for (std::uint64_t i = 0; i < 9 * 7 * 4; ++i)
        mask_px[mi].push_back(i < 8 || i % 11 == 0 ? 0 : noise(i * 17 + mi * 1000 + 3));
      masks.push_back({9, 7, mask_px[mi].data(), -0.3, 0.2, 0.9});
    }
    std::vector<BrushLayer> layers;
    for (int l = 0; l < cs.layers; ++l) layers.push_back({(l * 5) % 16, cs.period0 * (1 + 0.17 * l)});
    CompositeJob job;
    job.atlas = &at;
    job.layers = layers;
    job.masks = masks;
    job.origin_x_m = -0.41;
    job.origin_y_m = 0.77;
    job.m_per_texel = cs.m_per_texel;
    job.tile = cs.tile;
    job.border = cs.tile_border;
    const std::size_t side = static_cast<std::size_t>(cs.tile + 2 * cs.tile_border);
    std::vector<std::uint8_t> ref(side * side * 4);
    compose_reference(job, ref.data());
    Compositor c;
    for (ComposePath p : {ComposePath::kAuto, ComposePath::kGeneric, ComposePath::kAvx2}) {
      if (!compose_path_available(p)) continue;
      CAPTURE(static_cast<int>(p));
      std::vector<std::uint8_t> out(ref.size(), 7);
      c.compose(job, out.data(), p);
      CHECK(out == ref);
    }
  }
}

TEST_CASE("compositor: decals are drawn with their exact area coverage, alike on every path, and count_work counts what is drawn") {
  const Atlas at = build_atlas({comp_solid(16, 200, 0, 0)}, {}, {.cols = 1, .border = 2});
  const std::vector<std::uint8_t> mask = {255, 0, 0, 0};
  const WeightMask wm{1, 1, mask.data(), 0.0, 0.0, 2.0};
  const BrushLayer layer{0, 1.0};
  // Texels of 0.25 m over [0, 2) m. A: the top 4 rows whole, opaque. B: row 6 over half of texel 0
  // and half of texel 1 (coverage 1/2, alpha 200 -> a = 100). C: 0.2 m wide, under a texel: skipped.
  const Decal d[3] = {{0.0, 0.0, 2.0, 1.0, {0, 0, 250, 255}}, {0.125, 1.5, 0.375, 1.75, {10, 20, 30, 200}}, {1.0, 1.0, 1.2, 1.5, {9, 9, 9, 255}}};
  CompositeJob job;
  job.atlas = &at;
  job.layers = {&layer, 1};
  job.masks = {&wm, 1};
  job.m_per_texel = 0.25;
  job.tile = 8;
  job.decals = d;
  CHECK(count_work(job).decals == 2);
  CHECK(count_work(job).decal_texels == 8 * 4 + 2);  // A: 8 columns x 4 rows; B: texels 0 and 1 of row 6
  std::vector<std::uint8_t> ref(8 * 8 * 4);
  compose_reference(job, ref.data());
  const auto px = [&](int x, int y) { return std::vector<int>(ref.begin() + (y * 8 + x) * 4, ref.begin() + (y * 8 + x) * 4 + 4); };
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x) CHECK(px(x, y) == std::vector<int>{0, 0, 250, 255});
  // (200 * 155 + 10 * 100 + 127) / 255 = 125, (20 * 100 + 127) / 255 = 8, (30 * 100 + 127) / 255 = 12.
  CHECK(px(0, 6) == std::vector<int>{125, 8, 12, 255});
  CHECK(px(1, 6) == std::vector<int>{125, 8, 12, 255});
  CHECK(px(2, 6) == std::vector<int>{200, 0, 0, 255});
  CHECK(px(4, 5) == std::vector<int>{200, 0, 0, 255});  // under C
  Compositor c;
  for (ComposePath p : {ComposePath::kAuto, ComposePath::kGeneric, ComposePath::kAvx2}) {
    if (!compose_path_available(p)) continue;
    std::vector<std::uint8_t> out(ref.size(), 7);
    c.compose(job, out.data(), p);
    CHECK(out == ref);
  }
  std::vector<std::uint8_t> exact(ref.size());
  compose_exact(job, exact.data());
  CHECK(exact == ref);  // one brush colour: no rounding between the two
  // At 0.5 m texels a decal over [0.25, 0.75) x [1.75, 2.25) covers a quarter of texels (0, 3) and
  // (1, 3), the mean of the finer texels' coverage: a = round(0.25 x 200) = 50.
  job.m_per_texel = 0.5;
  job.tile = 4;
  CHECK(count_work(job).decals == 1);  // B is 0.25 m wide: under a 0.5 m texel, skipped; C too
  CHECK(count_work(job).decal_texels == 4 * 2);
  const Decal big[1] = {{0.25, 1.75, 0.75, 2.25, {10, 20, 30, 200}}};
  job.decals = big;
  CHECK(count_work(job).decal_texels == 2);  // columns 0-1 of row 3 (the rows below the tile are cut)
  std::vector<std::uint8_t> coarse(4 * 4 * 4);
  c.compose(job, coarse.data());
  const int a = 50, r = (200 * (255 - a) + 10 * a + 127) / 255;
  CHECK(static_cast<int>(coarse[(3 * 4 + 0) * 4]) == r);
  CHECK(static_cast<int>(coarse[(3 * 4 + 1) * 4]) == r);
}
