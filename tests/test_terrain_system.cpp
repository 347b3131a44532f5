#include <doctest/doctest.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/error.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "sim/trace/trace_gen.h"
#include "sim/view/scene.h"
#include "sim/run/systems.h"
#include "stream/system/terrain_system.h"

using namespace vtsim;

namespace {

// VT Terrain Design's terrain at vtsim's scale: 16 × 16 sectors of 512 m, 1024 texels/m (2^23 texels a side),
// clipsize 2048 in 256-texel tiles: 12 stack levels (0-11) over the pyramid (12-23).
std::vector<std::string> terrain_sets() {
  return {"texture.width=8388608", "texture.height=8388608", "texture.texels_per_m=1024", "texture.tile_size=256",
          "clipmap.clipsize=2048"};
}

ReplayConfig terrain_config(std::vector<std::string> extra = {}) {
  std::vector<std::string> sets = terrain_sets();
  sets.insert(sets.end(), extra.begin(), extra.end());
  return load_replay_config("", sets, "terrain");
}

struct Rig {
  ReplayConfig cfg = terrain_config();
  TerrainSystem sys{system_setup(cfg), cfg.clipmap, cfg.terrain};
  Pose pose;
  int f = 0;
  std::vector<Need> step(double x, double y) {
    pose.pos_m = {x, y, 1.7};
    SystemFrame sf;
    sf.frame = f++;
    sf.pose = &pose;
    sf.finest_needed = 0;
    sys.begin_frame(sf);
    std::vector<Need> needs;
    sys.emit_needs(needs);
    return needs;
  }
  // Commits everything needed until nothing is; returns the frames it took.
  int settle(double x, double y) {
    for (int i = 0; i < 100; ++i) {
      std::vector<Need> n = step(x, y);
      if (n.empty()) return i;
      for (const Need& k : n) sys.commit(k.key, f);
    }
    return -1;
  }
};

bool has_layer(const std::vector<Need>& n, std::uint32_t layer) {
  for (const Need& k : n)
    if (k.key.layer() == layer) return true;
  return false;
}

}  // namespace

TEST_CASE("terrain: levels map to brush mips and tiles to sectors") {
  Rig r;
  CHECK(r.sys.num_levels() == 24);
  CHECK(r.sys.clipmap().first_pyramid_level() == 12);
  CHECK(r.sys.sector_texels() == 524288);
  for (int l = 0; l < 24; ++l) CHECK(r.sys.brush_mip(l) == std::min(l, 4));
  int x0, x1, y0, y1;
  r.sys.tile_sectors(0, 4096 * 1024 / 256, 4096 * 1024 / 256, x0, x1, y0, y1);  // level-0 tile at (4096 m, 4096 m)
  CHECK(x0 == 8);
  CHECK(x1 == 8);
  CHECK(y0 == 8);
  r.sys.tile_sectors(11, 3, 5, x0, x1, y0, y1);  // a level-11 tile is 512 m: exactly one sector
  CHECK(x0 == 3);
  CHECK(x1 == 3);
  CHECK(y1 == 5);
  r.sys.tile_sectors(12, 1, 1, x0, x1, y0, y1);  // level 12: 1024 m, 2 × 2 sectors
  CHECK(x0 == 2);
  CHECK(x1 == 3);
  CHECK(y0 == 2);
  CHECK(y1 == 3);
}

TEST_CASE("terrain: a tile across sector boundaries needs every sector's brushes and blends 12 layers a texel") {
  Rig r;
  std::vector<Need> out;
  const Need tile{TileKey(0, 12, 1, 1), make_priority(12, 0, 0), false};
  // Before anything is resident, the level-12 tile (2 × 2 sectors) asks for 4 × 12 brush mips.
  std::vector<Need> n = r.step(4096, 4096);
  int l12 = 0;
  for (const Need& k : n)
    if (k.key.layer() == TerrainSystem::kBrushLayer && k.key.level() == 4) ++l12;
  CHECK(l12 == 256 * 12);  // the whole pyramid level 12 covers all 256 sectors at mip 4
  ProduceWork w;
  REQUIRE(r.sys.produced(tile.key, w));
  CHECK(w.texels == 256u * 256u);
  CHECK(w.layers == 12u);
  ProduceWork tail;
  REQUIRE(r.sys.produced(TileKey(0, 23, 0, 0), tail));  // the 1×1 level
  CHECK(tail.texels == 1u);
  std::uint64_t disk = 0, dec = 0;
  CHECK_FALSE(r.sys.tile_sizes(tile.key, disk, dec));
  REQUIRE(r.sys.tile_sizes(TileKey(TerrainSystem::kBrushLayer, 0, 5, 3), disk, dec));
  CHECK(dec == 4u * 1024u * 1024u);
  CHECK(disk == dec);
  REQUIRE(r.sys.tile_sizes(TileKey(TerrainSystem::kBrushLayer, 4, 5, 3), disk, dec));
  CHECK(dec == 4u * (4096u + 1024u + 256u + 64u + 16u + 4u + 1u));  // mip 4 and its tail
}

TEST_CASE("terrain: produced tiles are needed only once their brush mips are resident") {
  Rig r;
  std::vector<Need> n = r.step(4000, 4000);
  CHECK(has_layer(n, TerrainSystem::kBrushLayer));
  CHECK_FALSE(has_layer(n, 0));  // every tile is gated on its brushes
  CHECK(r.sys.gated_needs() > 0);
  for (const Need& k : n) CHECK(r.sys.commit(k.key, 0));
  n = r.step(4000, 4000);
  CHECK(has_layer(n, 0));
  CHECK_FALSE(has_layer(n, TerrainSystem::kBrushLayer));
  CHECK(r.sys.brush_loads() > 0);
  CHECK(r.sys.brush_bytes_resident() > 0);
}

TEST_CASE("terrain: the pyramid is produced once and its brushes are released") {
  Rig r;
  REQUIRE(r.settle(4000, 4000) > 0);
  CHECK(r.sys.produced_tiles(12) == 64);  // 8 × 8 tiles of 256 at level 12
  CHECK(r.sys.produced_tiles(23) == 1);
  const std::uint64_t releases = r.sys.brush_releases();
  CHECK(releases > 0);  // the pyramid's 3072 mip-4 brushes, but for the windows' sectors
  REQUIRE(r.settle(5500, 3000) > 0);
  CHECK(r.sys.produced_tiles(12) == 64);
  CHECK(r.sys.produced_tiles(23) == 1);
  CHECK(r.sys.brush_releases() > releases);  // the fine levels' old sectors
  CHECK(r.sys.produced_tiles(0) > 64);
}

TEST_CASE("terrain: a footprint invalidates the finest resident tiles under it, which are produced again") {
  Rig r;
  REQUIRE(r.settle(4000.5, 4000.5) > 0);
  const std::uint64_t before = r.sys.produced_tiles(0);
  r.sys.add_footprint(4000.5, 4000.5);
  CHECK(r.sys.invalidations() == 10);  // 0.3 m across 4000.5 m: 2 × 2 tiles at levels 0 (0.25 m) and 1 (0.5 m), 1 at levels 2, 3
  std::vector<Need> n = r.step(4000.5, 4000.5);
  REQUIRE(n.size() == 10);
  for (const Need& k : n) CHECK(r.sys.commit(k.key, r.f));
  CHECK(r.sys.produced_tiles(0) == before + 4);
  CHECK(r.step(4000.5, 4000.5).empty());
  ProduceWork w;
  REQUIRE(r.sys.produced(n[0].key, w));
  CHECK(w.decals >= 1);
}

TEST_CASE("terrain: capacity figures of VT Terrain Design, exact") {
  const TerrainCapacity c = terrain_capacity(TerrainConfig{}, 1024.0, 2048, 4096.0, 4096.0);
  CHECK(c.texels_side_x == 8388608);
  CHECK(c.stored_equiv_bytes == 281474976710656.0);  // 2^46 texels × 4 B = 256 TiB
  CHECK(c.brushes == 3072u);
  CHECK(c.brush_bytes_mip0 == 12884901888u);      // 12288 MiB
  CHECK(c.brush_bytes_all_mips == 17179865088u);  // 16383.996 MiB (seed: 16380)
  CHECK(c.masks == 768u);                         // 3 a sector (seed: 256)
  CHECK(c.mask_bytes == 805306368u);              // 768 MiB
  CHECK(c.full_levels == 13);
  CHECK(c.clipmap_full_levels_bytes == 218103808u);  // 208 MiB
  REQUIRE(c.level_sectors.size() == 12);
  CHECK(c.level_sectors[0] == 4);
  CHECK(c.level_sectors[11] == 64);
  CHECK(c.brush_resident_by_mip[0] == 201326592u);
  CHECK(c.brush_resident_by_mip[4] == 16776192u);
  CHECK(c.brush_resident_bytes == 284163072u);  // 271.0 MiB at a sector corner (seed: 264)
  const TerrainCapacity m = terrain_capacity(TerrainConfig{}, 1024.0, 2048, 4352.0, 4352.0);  // a sector's centre
  CHECK(m.level_sectors[0] == 1);
  CHECK(m.level_sectors[11] == 81);
  CHECK(m.brush_resident_bytes == 50331648u + 12582912u + 3145728u + 786432u + 81u * 12u * 21844u);
}

TEST_CASE("terrain: bad configs name the field") {
  const auto fails = [](std::vector<std::string> extra, const std::string& field) {
    try {
      (void)terrain_config(std::move(extra));
      FAIL("accepted");
    } catch (const InputError& e) {
      CHECK_MESSAGE(std::string(e.what()).find(field) != std::string::npos, e.what());
    }
  };
  fails({"terrain.brushes_per_sector=17"}, "terrain.brushes_per_sector");
  fails({"terrain.brush_size=1000"}, "terrain.brush_size");
  fails({"terrain.mask_size=1000"}, "terrain.mask_size");
  fails({"texture.width=4194304"}, "texture.width");
  fails({"terrain.brush_period_m=3"}, "texture.texels_per_m");
  fails({"terrain.brush_tree_levels=12"}, "terrain.brush_tree_levels");
  fails({"texture.border=4"}, "texture.border");
}

// The throttle's service rate of a produced system is its production (SystemRun::service_Bps):
// with one tile produced a frame the fine levels' backlog outruns the deadline and the clamp
// engages naming the level; with free production nothing is clamped. Before, the terrain's rate
// was the disk's, for tiles never read, and one tile a frame never clamped (docs/produced.md,
// "Production per frame").
TEST_CASE("terrain: the throttle reads the production rate and clamps the level that falls behind") {
  const std::vector<std::string> small = {
      "texture.width=4096",  "texture.height=4096", "texture.texels_per_m=64", "texture.tile_size=64",
      "clipmap.clipsize=256", "terrain.sectors_x=4", "terrain.sectors_y=4",    "terrain.sector_m=16",
      "terrain.brushes_per_sector=4", "terrain.brush_size=64", "terrain.brush_tree_levels=3",
      "terrain.mask_size=64", "view.divisor=16", "throttle.policy=deadline"};
  TraceGenParams g = default_gen_params("walk");
  g.start_m = {28.0, 32.0};
  g.speed_mps = 4.0;
  g.duration_s = 3.0;
  g.image_width = 640;
  g.image_height = 360;
  const Trace t = generate_trace(g);
  auto run = [&](std::vector<std::string> extra) {
    std::vector<std::string> sets = small;
    sets.insert(sets.end(), extra.begin(), extra.end());
    const ReplayConfig c = load_replay_config("", sets, "terrain");
    const std::unique_ptr<IScene> scene = make_scene_from_config(c);
    return run_replay(c, t, *scene).summary;
  };
  const nlohmann::json slow = run({"produce.workers=1", "produce.tiles_per_frame=1"});
  REQUIRE(slow["throttle"]["frames_throttled"].get<int>() > 0);
  const std::string reason = slow["throttle"]["lod_timeline"][0]["reason"].get<std::string>();
  CHECK(reason.rfind("engage: backlog from level 0 needs ", 0) == 0);
  CHECK(slow["throttle"]["lod_timeline"][0]["to"].get<int>() > 0);
  const nlohmann::json quick = run({"produce.per_tile_us=0", "produce.per_texel_ns=0", "produce.per_layer_texel_ns=0",
                                   "produce.per_decal_us=0"});
  CHECK(quick["throttle"]["frames_throttled"].get<int>() == 0);
  CHECK(quick["produce"]["produced"].get<int>() > 0);
}
