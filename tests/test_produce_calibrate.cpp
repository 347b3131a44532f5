// Calibrating the produce stage (docs/produced.md "Calibration"): the least-squares fit of
// ProduceModel recovers a known model exactly, drops negative terms, refuses degenerate samples;
// the procedural scene activates exactly the layers asked for.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
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
  // Texels never vary: the intercept cannot be told from the per-texel terms; it is folded into them, and said.
  const ProduceFit f = fit_produce_model(one_size);
  CHECK(f.model.per_tile_us == 0);
  REQUIRE(f.notes.size() == 1);
  CHECK(f.notes[0] == "every sample is 4096 texels: per_tile_us folded into the per-texel terms (fixed at 0)");
  CHECK(f.model_ms == doctest::Approx(f.measured_ms).epsilon(1e-9));
  CHECK_THROWS_WITH_AS(fit_produce_model({{4096, 1, 0, 100.0}, {16, 2, 0, 10.0}}), doctest::Contains("2 samples for 3 unknowns"), InputError);
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

namespace {

// A replay's tiles as the terrain makes them: every one blends 12 layers; full 264² tiles (256 and
// a border of 4) and a coarse level's partial squares; decals of varying sizes over some.
std::vector<ProducedTile> pcal_replay_tiles(const ProduceModel& m) {
  std::vector<ProducedTile> t;
  for (int i = 0; i < 40; ++i) {
    const std::uint64_t side = i % 5 == 4 ? 16u << (i % 3) : 264u;
    const std::uint32_t decals = static_cast<std::uint32_t>(i % 4);
    const ProduceWork w{side * side, 12, decals, decals * static_cast<std::uint64_t>(100 + 37 * i)};
    t.push_back({static_cast<std::uint32_t>(side == 264 ? i % 4 : 6), w, produce_ns(m, w), produce_ns(m, w) * 0.75});
  }
  return t;
}

}  // namespace

TEST_CASE("produce calibration from a replay's tiles: one layer count folds per_texel_ns into per_layer_texel_ns, exactly") {
  ProduceModel truth;
  truth.per_tile_us = 6.0;
  truth.per_texel_ns = 0.6;
  truth.per_layer_texel_ns = 1.8;
  truth.per_decal_us = 0.25;
  truth.per_decal_texel_ns = 2.5;
  const std::vector<ProducedTile> tiles = pcal_replay_tiles(truth);
  const ProduceFit f = fit_produce_model(samples_from_tiles(tiles, false));
  CHECK(f.decals_fitted);
  CHECK(f.model.per_texel_ns == 0);
  CHECK(f.model.per_layer_texel_ns == doctest::Approx(1.8 + 0.6 / 12).epsilon(1e-9));
  CHECK(f.model.per_tile_us == doctest::Approx(6.0).epsilon(1e-9));
  CHECK(f.model.per_decal_us == doctest::Approx(0.25).epsilon(1e-9));
  CHECK(f.model.per_decal_texel_ns == doctest::Approx(2.5).epsilon(1e-9));
  CHECK(f.max_rel_error < 1e-9);
  CHECK(f.model_ms == doctest::Approx(f.measured_ms).epsilon(1e-9));
  REQUIRE(f.notes.size() == 1);
  CHECK(f.notes[0] == "every sample blends 12 layers: per_texel_ns folded into per_layer_texel_ns (fixed at 0; the fit holds for 12 layers)");
  // Their CPU time instead: every coefficient three quarters.
  const ProduceFit c = fit_produce_model(samples_from_tiles(tiles, true));
  CHECK(c.model.per_layer_texel_ns == doctest::Approx(0.75 * (1.8 + 0.6 / 12)).epsilon(1e-9));
  // All full tiles: the intercept is folded too, and said.
  std::vector<ProducedTile> full;
  for (const ProducedTile& p : tiles)
    if (p.work.texels == 264u * 264u) full.push_back(p);
  const ProduceFit g = fit_produce_model(samples_from_tiles(full, false));
  CHECK(g.model.per_tile_us == 0);
  CHECK(g.notes.size() == 2);
  CHECK(g.notes[1].find("per_tile_us folded") != std::string::npos);
  CHECK(g.model_ms == doctest::Approx(g.measured_ms).epsilon(1e-6));
  // Noisy tiles (every third 30 % slower, every fifth 20 % faster): the absolute fit's sum is theirs,
  // the relative fit's is not.
  ProduceModel fixed_cost = truth;
  fixed_cost.per_tile_us = 800;  // as the terrain's tiles measured (docs/produced.md): every term stays positive
  std::vector<ProducedTile> noisy = pcal_replay_tiles(fixed_cost);
  for (std::size_t i = 0; i < noisy.size(); ++i) noisy[i].wall_ns *= i % 3 == 0 ? 1.3 : i % 5 == 0 ? 0.8 : 1.0;
  const ProduceFit na = fit_produce_model(samples_from_tiles(noisy, false), {}, false);
  CHECK_FALSE(na.relative);
  CHECK(na.model_ms == doctest::Approx(na.measured_ms).epsilon(1e-9));
  const ProduceFit nr = fit_produce_model(samples_from_tiles(noisy, false));
  CHECK(std::fabs(nr.model_ms / nr.measured_ms - 1) > 1e-3);
  CHECK(produce_profile_toml(na, samples_from_tiles(noisy, false)).find("fitted by `vtsim calibrate --samples`") != std::string::npos);
  // A profile of thousands of tiles groups them by (texels, layers) instead of listing each.
  std::vector<ProducedTile> many;
  for (int r = 0; r < 4; ++r) many.insert(many.end(), tiles.begin(), tiles.end());
  const std::vector<ProduceSample> ms = samples_from_tiles(many, false);
  const std::string prof = produce_profile_toml(fit_produce_model(ms), ms);
  CHECK(prof.find("#   texels layers  tiles") != std::string::npos);
  CHECK(prof.find("#    69696     12    128") != std::string::npos);  // 32 full tiles of the 40, four times
  CHECK((prof.find(" ms (+0.0 %)") != std::string::npos || prof.find(" ms (-0.0 %)") != std::string::npos));
}

TEST_CASE("produced-tiles CSV: round trip, and every bad row named by file, line and column") {
  test::RealScratch dir;
  ProduceModel m;
  const std::vector<ProducedTile> tiles = pcal_replay_tiles(m);
  const std::string csv = produced_tiles_csv(tiles);
  {
    std::ofstream(dir.file("t.csv")) << csv;
  }
  const std::vector<ProducedTile> back = read_produced_tiles_csv(dir.file("t.csv"));
  REQUIRE(back.size() == tiles.size());
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    CHECK(back[i].level == tiles[i].level);
    CHECK(back[i].work.texels == tiles[i].work.texels);
    CHECK(back[i].work.layers == tiles[i].work.layers);
    CHECK(back[i].work.decals == tiles[i].work.decals);
    CHECK(back[i].work.decal_texels == tiles[i].work.decal_texels);
    CHECK(std::fabs(back[i].wall_ns - tiles[i].wall_ns) <= 0.5 + 1e-6);  // written to the ns (a steady clock's resolution)
    CHECK(std::fabs(back[i].cpu_ns - tiles[i].cpu_ns) <= 0.5 + 1e-6);
  }
  const std::string head = "level,texels,layers,decals,decal_texels,wall_us,cpu_us\n";
  const auto refused = [&](const std::string& text) -> std::string {
    std::ofstream(dir.file("bad.csv"), std::ios::trunc) << text;
    try {
      read_produced_tiles_csv(dir.file("bad.csv"));
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  };
  const std::string bad = dir.file("bad.csv");
  CHECK(refused("") == bad + ": empty: expected the header 'level,texels,layers,decals,decal_texels,wall_us,cpu_us'");
  CHECK(refused("level,texels\n").find(bad + ":1: header 'level,texels' is not") == 0);
  CHECK(refused(head + "0,100,12,0,0,5.0,4.0\n1,100,12,0,0,5.0\n") == bad + ":3: 6 fields, expected 7 (" + head.substr(0, head.size() - 1) + ")");
  CHECK(refused(head + "0,100,12,0,0,5.0,4.0,9\n").find(bad + ":2: 8 fields") == 0);
  CHECK(refused(head + "0,100,12,0,0,fast,4.0\n") == bad + ":2: column 'wall_us': 'fast' is not a time > 0, us");
  CHECK(refused(head + "0,100,12,0,0,nan,4.0\n").find("column 'wall_us'") != std::string::npos);
  CHECK(refused(head + "0,100,12,0,0,0,4.0\n").find("column 'wall_us'") != std::string::npos);
  CHECK(refused(head + "0,0,12,0,0,5,4.0\n") == bad + ":2: column 'texels': '0' is not a texel count >= 1");
  CHECK(refused(head + "64,100,12,0,0,5,4.0\n").find("column 'level'") != std::string::npos);
  CHECK(refused(head + "0,100,-1,0,0,5,4.0\n").find("column 'layers'") != std::string::npos);
  CHECK(refused(head + "0,100,12,0,0,5,-1\n").find("column 'cpu_us'") != std::string::npos);
  CHECK(refused(head + "\n0,100,12,0,0,5,4\r\n") == "accepted");  // blank lines and CRLF
  CHECK(read_produced_tiles_csv(dir.file("bad.csv")).size() == 1);
  std::filesystem::create_directory(dir.file("d"));
  CHECK_THROWS_WITH_AS(read_produced_tiles_csv(dir.file("d")), doctest::Contains("directory"), InputError);
}
