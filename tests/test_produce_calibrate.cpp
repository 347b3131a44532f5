// Calibrating the produce stage (docs/produced.md "Calibration"): the least-squares fit of
// ProduceModel recovers a known model exactly, drops negative terms, refuses degenerate samples;
// the procedural scene activates exactly the layers asked for.
#include <doctest/doctest.h>

#include <vector>

#include "core/error.h"
#include "real_test_util.h"
#include "stream/produce/produce_calibrate.h"

using namespace vtsim;
using namespace vtsim::produce;

namespace {

// decal_side: each decal touches decal_side(tile)² texels (0: the samples count no decal texels).
std::vector<ProduceSample> pcal_synthetic(const ProduceModel& m, bool decals, int (*decal_side)(int) = nullptr) {
  std::vector<ProduceSample> s;
  for (int tile : {64, 128, 256, 512})
    for (int border : {0, 4})
      for (std::uint32_t layers : {1u, 2u, 8u, 16u})
        for (std::uint32_t d : decals ? std::vector<std::uint32_t>{0, 5} : std::vector<std::uint32_t>{0}) {
          const std::uint64_t texels = static_cast<std::uint64_t>(tile + 2 * border) * static_cast<std::uint64_t>(tile + 2 * border);
          const std::uint64_t side = decal_side ? static_cast<std::uint64_t>(decal_side(tile)) : 0;
          const ProduceWork w{texels, layers, d, d * side * side};
          s.push_back({texels, layers, d, produce_ns(m, w), tile, border, w.decal_texels});
        }
  return s;
}

}  // namespace

TEST_CASE("produce calibration: the fit recovers an exact model") {
  ProduceModel truth;
  truth.per_tile_us = 7.5;
  truth.per_texel_ns = 0.75;
  truth.per_layer_texel_ns = 1.625;
  truth.per_decal_us = 3.0;
  ProduceModel base;
  base.workers = 3;
  base.per_decal_us = 9.0;
  SUBCASE("three terms, decals kept from the base") {
    const ProduceFit f = fit_produce_model(pcal_synthetic(truth, false), base);
    CHECK_FALSE(f.decals_fitted);
    CHECK(f.model.per_tile_us == doctest::Approx(7.5).epsilon(1e-9));
    CHECK(f.model.per_texel_ns == doctest::Approx(0.75).epsilon(1e-9));
    CHECK(f.model.per_layer_texel_ns == doctest::Approx(1.625).epsilon(1e-9));
    CHECK(f.model.per_decal_us == 9.0);
    CHECK(f.model.workers == 3);
    CHECK(f.max_rel_error < 1e-9);
    CHECK(f.notes.empty());
  }
  SUBCASE("four terms") {
    const ProduceFit f = fit_produce_model(pcal_synthetic(truth, true), base);
    CHECK(f.decals_fitted);
    CHECK(f.model.per_tile_us == doctest::Approx(7.5).epsilon(1e-9));
    CHECK(f.model.per_decal_us == doctest::Approx(3.0).epsilon(1e-9));
    CHECK(f.model.per_decal_texel_ns == 0);
    CHECK(f.max_rel_error < 1e-9);
  }
  SUBCASE("five terms: decals of tile/8 a side, so the texels per decal differ between tile sizes") {
    truth.per_decal_texel_ns = 2.5;
    const ProduceFit f = fit_produce_model(pcal_synthetic(truth, true, [](int tile) { return tile / 8; }), base);
    CHECK(f.decals_fitted);
    CHECK(f.model.per_layer_texel_ns == doctest::Approx(1.625).epsilon(1e-9));
    CHECK(f.model.per_decal_us == doctest::Approx(3.0).epsilon(1e-9));
    CHECK(f.model.per_decal_texel_ns == doctest::Approx(2.5).epsilon(1e-9));
    CHECK(f.max_rel_error < 1e-9);
  }
  SUBCASE("decals of one size everywhere: per decal and per decal texel are one column, the texels fitted alone") {
    truth.per_decal_us = 0;
    truth.per_decal_texel_ns = 2.5;
    const ProduceFit f = fit_produce_model(pcal_synthetic(truth, true, [](int) { return 16; }), base);
    CHECK(f.decals_fitted);
    CHECK(f.model.per_decal_us == 0);
    CHECK(f.model.per_decal_texel_ns == doctest::Approx(2.5).epsilon(1e-9));
    CHECK(f.max_rel_error < 1e-9);
  }
}

TEST_CASE("produce calibration: a negative term is fixed at 0 and the rest refitted") {
  ProduceModel truth;
  truth.per_tile_us = 0;
  truth.per_texel_ns = 2.0;
  truth.per_layer_texel_ns = 1.0;
  std::vector<ProduceSample> s = pcal_synthetic(truth, false);
  for (ProduceSample& p : s) p.ns -= 3000;  // a negative intercept: -3 us
  const ProduceFit f = fit_produce_model(s);
  CHECK(f.model.per_tile_us == 0);
  CHECK(f.model.per_texel_ns > 0);
  CHECK(f.model.per_layer_texel_ns > 0);
  REQUIRE(f.notes.size() == 1);
  CHECK(f.notes[0].find("per_tile_us") != std::string::npos);
}

TEST_CASE("produce calibration: degenerate or bad samples are refused") {
  ProduceModel truth;
  std::vector<ProduceSample> one_size;
  for (std::uint32_t l : {1u, 2u, 4u}) one_size.push_back({4096, l, 0, produce_ns(truth, ProduceWork{4096, l, 0})});
  CHECK_THROWS_AS(fit_produce_model(one_size), InputError);  // texels never vary: intercept and per-texel inseparable
  CHECK_THROWS_AS(fit_produce_model({{4096, 1, 0, 100.0}}), InputError);
  CHECK_THROWS_WITH_AS(fit_produce_model({{4096, 1, 0, 0.0}, {16, 1, 0, 1.0}, {64, 2, 0, 1.0}}), doctest::Contains("must be > 0"),
                       InputError);
}

TEST_CASE("produce calibration: the procedural scene blends exactly the layers asked for") {
  const ProduceScene scene(8, 64, 8, 32, 512.0, 3);
  std::vector<std::uint8_t> out(36 * 36 * 4);
  Compositor c;
  for (int layers : {1, 4, 5, 8}) {
    const CompositeJob j = scene.job(layers, 1.0, 10.0, 20.0, 0.0, 0.0, 1.0 / 64, 32, 2);
    const ProduceWork w = count_work(j);
    CHECK(w.layers == static_cast<std::uint32_t>(layers));
    CHECK(w.texels == 36u * 36u);
    c.compose(j, out.data());
  }
  CHECK_THROWS_AS(scene.job(9, 1.0, 0, 0, 0, 0, 1.0, 32, 0), InputError);
}

TEST_CASE("produce calibration: a tiny measurement fits") {
  ProduceMeasureOptions o;
  o.tiles = {16, 32};
  o.borders = {0, 2};
  o.layers = {1, 4};
  o.decals = {0};
  o.repeats = 1;
  o.brush_side = 32;
  const std::vector<ProduceSample> s = measure_compositor(o);
  REQUIRE(s.size() == 8);
  for (const ProduceSample& p : s) CHECK(p.ns > 0);
  const ProduceFit f = fit_produce_model(s);
  CHECK(f.model.per_layer_texel_ns >= 0);
  CHECK(produce_profile_toml(f, s).find("[produce]\nper_tile_us = ") != std::string::npos);
}

TEST_CASE("vtsim calibrate --produce: a quick run writes the [produce] keys, a config the simulated clock takes") {
  test::RealScratch dir;
  auto r = test::run_cli(dir, "calibrate --produce --quick -q --produce-workers 3 -o " + dir.file("p.toml"));
  REQUIRE(r.code == 0);
  const std::string prof = test::slurp(dir.file("p.toml"));
  CHECK(prof.find("[produce]\nper_tile_us = ") != std::string::npos);
  CHECK(prof.find("per_layer_texel_ns = ") != std::string::npos);
  CHECK(prof.find("workers = 3") != std::string::npos);
  r = test::run_cli(dir, "replay --config " + dir.file("p.toml") + " --print-config");
  CHECK(r.code == 0);
  CHECK(r.out.find("produce.per_layer_texel_ns") != std::string::npos);
  r = test::run_cli(dir, "calibrate -q");
  CHECK(r.code == 2);
  CHECK(r.err.find("--store: required") != std::string::npos);
  r = test::run_cli(dir, "calibrate --produce --store x.vts -q");
  CHECK(r.code == 2);
  CHECK(r.err.find("--produce measures the compositor") != std::string::npos);
  r = test::run_cli(dir, "calibrate --produce --quick -q --produce-texel-m 0");
  CHECK(r.code == 2);
  CHECK(r.err.find("--produce-texel-m: 0 (an output texel in metres, > 0)") != std::string::npos);
  // The profile names the decal keys (not measured by --quick, which draws no decals: kept).
  CHECK(prof.find("per_decal_texel_ns = 2.4  # not measured: kept") != std::string::npos);
}
