// Issue 27: the three systems side by side (docs/produced.md, "Three systems side by side") and the
// terrain's `vtsim capacity` report (docs/produced.md, "Capacity: VT Terrain Design checked").
#include <doctest/doctest.h>

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "sim/sweep/sweep.h"
#include "sim/sweep/sweep_table.h"
#include "store_test_util.h"
#include "test_util.h"

using namespace vtsim;

namespace {

void compare_write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

// A small terrain: 2 × 2 sectors of 64 m at 128 texels/m (16384 texels a side; brushes of 1024 per
// metre, mip offset 3), clipsize 1024 in 128-texel tiles; the three systems on one half-second walk.
constexpr const char* kThreeSystems = R"(name = "three systems, tiny"
set = ["texture.width=16384", "texture.height=16384", "texture.texels_per_m=128", "texture.tile_size=128",
       "clipmap.clipsize=1024", "terrain.sectors_x=2", "terrain.sectors_y=2", "terrain.sector_m=64", "vt.pool_pages=256"]
generate = ["walk duration_s=0.5 start_m=60,60"]
[[configs]]
"run.system" = "vt"
[[configs]]
"run.system" = "clipmap"
[[configs]]
"run.system" = "terrain"
)";

}  // namespace

TEST_CASE("systems: one sweep row per system, production time only for the terrain, one table with a column per metric") {
  test::TempDir d;
  compare_write(d.file("spec.toml"), kThreeSystems);
  SweepOptions o;
  o.out_dir = d.file("o");
  o.jobs = 1;
  run_sweep(load_sweep_spec(d.file("spec.toml")), o);
  const SweepOutputs out = load_sweep_outputs(d.file("o"));
  REQUIRE(out.rows.size() == 3);
  SweepTableSpec t;
  t.rows = {"run.system"};
  t.col = "metric";
  t.metrics = {"resources.produce_ms_per_frame.mean", "resources.produce_ms_per_frame.max", "resources.vram_bytes",
               "resources.disk_stored_bytes", "popin.blurry_fraction_p95"};
  t.csv = true;
  const std::string csv = sweep_table(out, t);
  // metric,run.system,value: one line per (metric, system).
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  CHECK(line == "metric,run.system,value");
  std::map<std::string, std::map<std::string, double>> v;
  std::size_t n = 0;
  while (std::getline(in, line)) {
    const auto a = line.find(','), b = line.find(',', a + 1);
    REQUIRE(b != std::string::npos);
    v[line.substr(0, a)][line.substr(a + 1, b - a - 1)] = std::stod(line.substr(b + 1));
    ++n;
  }
  CHECK(n == 3 * t.metrics.size());
  for (const char* m : {"resources.produce_ms_per_frame.mean", "resources.produce_ms_per_frame.max"}) {
    CAPTURE(m);
    REQUIRE(v[m].size() == 3);
    CHECK(v[m]["vt"] == 0.0);
    CHECK(v[m]["clipmap"] == 0.0);
    CHECK(v[m]["terrain"] > 0.0);
  }
  // VRAM: the VT's pool (256 pages of 128² × 4 B); the clipmaps' windows and pyramid, the terrain's
  // plus its brushes. Disk: the store of 16384² texels in 128² tiles, every level; the terrain's
  // 48 brushes with every mip and 12 masks of 512².
  CHECK(v["resources.vram_bytes"]["vt"] == 256.0 * 128 * 128 * 4);
  CHECK(v["resources.vram_bytes"]["terrain"] > v["resources.vram_bytes"]["clipmap"]);
  CHECK(v["resources.disk_stored_bytes"]["terrain"] == 48.0 * 4 * (1398101.0) + 12.0 * 512 * 512 * 4);
  CHECK(v["resources.disk_stored_bytes"]["clipmap"] > v["resources.disk_stored_bytes"]["terrain"]);

  // The Markdown form: a header of the row keys and metrics, one line per system, in config order.
  t.csv = false;
  const std::string md = sweep_table(out, t);
  CHECK(md.rfind("| run.system | resources.produce_ms_per_frame.mean |", 0) == 0);
  CHECK(test::contains(md, "\n| vt | 0 | 0 |"));
  CHECK(test::contains(md, "\n| clipmap | 0 | 0 |"));
  CHECK(test::contains(md, "\n| terrain | "));
  SweepTableSpec bad = t;
  bad.rows = {"trace"};  // three systems in one line
  CHECK_THROWS_WITH_AS(sweep_table(out, bad), doctest::Contains("add run.system to --rows or --col"), InputError);
}

TEST_CASE("systems: vtsim capacity --system terrain carries VT Terrain Design's figures, text and JSON, and names bad fields") {
  test::TempDir d;
  const std::string cfg = std::string(" -c ") + VTSIM_SOURCE_DIR + "/docs/examples/terrain.toml";
  test::CliRun r = test::run_vtsim_capture("capacity --system terrain --json" + cfg, d.file("err"));
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(r.out);
  CHECK(j["terrain"]["texels"][0] == 8388608);
  CHECK(j["stored_texel_bytes"].get<double>() == 281474976710656.0);  // 2^46 texels × 4 B = 256 TiB
  CHECK(j["far_cry_4_stored_texel_bytes"].get<double>() == 4e14);    // Far Cry 4's 10 km: 363.8 TiB
  CHECK(j["brushes"] == 3072);
  CHECK(j["brush_bytes_mip0"] == 12884901888ull);
  CHECK(j["brush_bytes_all_mips"] == 17179865088ull);
  CHECK(j["masks"] == 768);
  CHECK(j["mask_bytes"] == 805306368ull);
  CHECK(j["stored_bytes"] == 17179865088ull + 805306368ull);
  CHECK(j["clipmap"]["full_levels"] == 13);
  CHECK(j["clipmap"]["full_levels_bytes"] == 218103808ull);
  CHECK(j["camera_m"][0].get<double>() == 4096.0);
  REQUIRE(j["levels"].size() == 12);
  CHECK(j["levels"][0]["sectors"] == 4);
  CHECK(j["levels"][0]["brush_mip"] == 0);
  CHECK(j["levels"][0]["brush_bytes"] == 4ull * 12 * 4194304);
  CHECK(j["levels"][11]["sectors"] == 64);
  CHECK(j["levels"][11]["brush_mip"] == 4);
  CHECK(j["brush_resident_by_mip"][0] == 201326592ull);
  CHECK(j["brush_resident_by_mip"][4] == 16776192ull);
  CHECK(j["brush_resident_bytes"] == 284163072ull);  // 271.0 MiB at a sector corner

  r = test::run_vtsim_capture("capacity --system terrain --camera 4352,4352" + cfg, d.file("err"));
  REQUIRE(r.code == 0);
  CHECK(test::contains(r.out, "256.00 TiB (281,474,976,710,656 B); Far Cry 4's 10 km at 10 texels/cm: 363.80 TiB"));
  CHECK(test::contains(r.out, "12288.0 MiB at mip 0; every mip 16384.0 MiB (17,179,865,088 B)"));
  CHECK(test::contains(r.out, "768 (3 a sector) × 512² × 4 B = 768.0 MiB"));
  CHECK(test::contains(r.out, "13 levels × 2048² × 4 B = 208.0 MiB"));
  CHECK(test::contains(r.out, "camera at (4352, 4352) m"));
  // At a sector's centre: mips 0-3 on that one sector, mip 4 with its tail on 9 × 9.
  CHECK(test::contains(r.out, "= 88,079,088 B"));

  for (const auto& [args, field] : std::vector<std::pair<std::string, std::string>>{
           {"--set terrain.brushes_per_sector=17", "terrain.brushes_per_sector"},
           {"--set terrain.brush_size=1000", "terrain.brush_size"},
           {"--camera 9000,1", "--camera"},
           {"--camera x", "--camera"}}) {
    const auto& args_ = args;  // clang 14 cannot capture a structured binding (CAPTURE's lambda)
    CAPTURE(args_);
    r = test::run_vtsim_capture("capacity --system terrain " + args + cfg, d.file("err"));
    CHECK(r.code == 2);
    CHECK_MESSAGE(test::contains(r.err, field), r.err);
  }
  r = test::run_vtsim_capture("capacity --camera 1,1", d.file("err"));
  CHECK(r.code == 2);
  CHECK(test::contains(r.err, "--camera"));
}
