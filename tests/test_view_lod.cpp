#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "sim/view/lod.h"
#include "core/view.h"

using namespace vtsim;

TEST_CASE("fast_log2 is exact at powers of two and within 1e-11 elsewhere") {
  for (int e = -128; e <= 128; ++e) CHECK(fast_log2(std::ldexp(1.0, e)) == static_cast<double>(e));
  double worst = 0.0;
  // Dense sweep over the mantissa around the reduction boundary and a few decades.
  for (int k = 0; k < 200000; ++k) {
    const double x = std::ldexp(1.0 + k / 200000.0, (k % 61) - 30);
    worst = std::max(worst, std::fabs(fast_log2(x) - std::log2(x)));
  }
  CHECK(worst < 1e-11);
  // Monotone across table cells and binades.
  for (int i = 1; i <= 256; ++i) {
    const double s = 1.0 + i / 256.0;
    CHECK(fast_log2(std::nextafter(s, 0.0)) <= fast_log2(s));
    CHECK(fast_log2(s) <= fast_log2(std::nextafter(s, 4.0)));
  }
}

TEST_CASE("lod_from_lengths2: Heckbert max / anisotropic ratio clamp / bias / finite clamps") {
  LodRule iso;
  CHECK(lod_from_lengths2(16.0, 4.0, iso) == 2.0);   // max(|dx|, |dy|) = 4 texels -> 2
  CHECK(lod_from_lengths2(1.0, 64.0, iso) == 3.0);
  LodRule b = iso;
  b.bias = -0.5;
  CHECK(lod_from_lengths2(16.0, 4.0, b) == 1.5);
  LodRule an;
  an.anisotropic = true;
  an.inv_aniso2 = 1.0 / (4.0 * 4.0);  // max_aniso 4
  CHECK(lod_from_lengths2(64.0, 16.0, an) == 2.0);     // ratio 2 <= 4: log2(minor) = log2 4
  CHECK(lod_from_lengths2(4096.0, 1.0, an) == 4.0);    // ratio 64 > 4: log2(64 / 4)
  CHECK(lod_from_lengths2(4096.0, 0.0, an) == 4.0);    // minor 0: no division by zero
  // Degenerate footprints stay finite: [-64, 64] before bias.
  CHECK(lod_from_lengths2(0.0, 0.0, iso) == -64.0);
  CHECK(lod_from_lengths2(std::numeric_limits<double>::infinity(), 1.0, iso) == 64.0);
  CHECK(lod_from_lengths2(std::nan(""), std::nan(""), iso) == -64.0);
  CHECK(lod_from_lengths2(1e300, 1e300, an) == 64.0);
}

TEST_CASE("desired_level floors and clamps") {
  CHECK(desired_level(-3.0f, 10) == 0);
  CHECK(desired_level(0.0f, 10) == 0);
  CHECK(desired_level(0.999f, 10) == 0);
  CHECK(desired_level(1.0f, 10) == 1);
  CHECK(desired_level(9.5f, 10) == 9);
  CHECK(desired_level(64.0f, 10) == 9);
  CHECK(desired_level(std::nanf(""), 10) == 0);
  CHECK(mip_level_count({1, 1}) == 1);
  CHECK(mip_level_count({1 << 20, 1 << 20}) == 21);
  CHECK(mip_level_count({1000, 3}) == 11);  // 1000 500 250 125 63 32 16 8 4 2 1
}
