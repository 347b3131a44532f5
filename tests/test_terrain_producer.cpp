// The terrain in the real clock (docs/produced.md, "The real clock"): the TerrainProducer composes
// a tile to the same bytes on any thread, serves brush mips from its atlas, and a short real-clock
// replay of a small terrain produces its tiles into the VRAM arena, byte-exact; the CLI runs it
// without a store and names what it cannot run.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstring>
#include <thread>

#include "real_test_util.h"
#include "sim/run/real_replay.h"
#include "sim/trace/trace_gen.h"
#include "sim/trace/trace_io.h"
#include "sim/view/scene.h"
#include "stream/exec/threaded_executor.h"
#include "stream/produce/terrain_producer.h"
#include "stream/store/store_builder.h"
#include "stream/system/terrain_system.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;

namespace {

// A small terrain: 4 × 4 sectors of 16 m at 64 texels/m (4096² texels, 13 levels), 64-texel tiles,
// a 256² clipmap (4 stack levels over the pyramid), 4 brushes of 64² a sector (brush mip = level),
// a 3-level brush quadtree.
const std::vector<std::string> kSmallTerrain = {
    "run.system=terrain",           "texture.width=4096",          "texture.height=4096",
    "texture.texels_per_m=64",      "texture.tile_size=64",        "clipmap.clipsize=256",
    "terrain.sectors_x=4",          "terrain.sectors_y=4",         "terrain.sector_m=16",
    "terrain.brushes_per_sector=4", "terrain.brush_size=64",       "terrain.brush_tree_levels=3",
    "terrain.mask_size=64",         "terrain.decals_static=16",    "terrain.decal_size_m=1",
    "view.divisor=16",              "view.render_threads=0",       "produce.workers=2"};

ReplayConfig small_terrain(const std::vector<std::string>& more = {}) {
  ReplayConfig c;
  for (const std::string& s : kSmallTerrain) apply_set(replay_config_table(), c, s);
  for (const std::string& s : more) apply_set(replay_config_table(), c, s);
  validate(c);
  return c;
}

Trace small_walk(double seconds) {
  TraceGenParams g = default_gen_params("walk");
  g.start_m = {28.0, 32.0};
  g.speed_mps = 4.0;
  g.duration_s = seconds;
  g.image_width = 640;
  g.image_height = 360;
  return generate_trace(g);
}

TileJob tile_job(const ReplayConfig& c, TileKey key) {
  TileJob j;
  j.key = key;
  const std::int64_t lw = (c.texture.width + (std::int64_t{1} << key.level()) - 1) >> key.level();
  const std::int64_t w = std::clamp<std::int64_t>(lw - static_cast<std::int64_t>(key.x()) * c.texture.tile_size, 0, c.texture.tile_size);
  j.produce.texels = static_cast<std::uint64_t>(w * w);
  j.produce.layers = static_cast<std::uint32_t>(c.terrain.brushes_per_sector);
  return j;
}

}  // namespace

TEST_CASE("terrain producer: a tile composes to the same bytes twice and on another thread, brush mips come from the atlas") {
  const ReplayConfig c = small_terrain();
  produce::TerrainProducerParams params = terrain_producer_params(c);
  params.border = 2;  // the clipmap's borders are 0; the producer composes any (a VT page's)
  produce::TerrainProducer p(params);
  const TileJob job = tile_job(c, TileKey(0, 1, 5, 3));
  TileData a, b, t;
  p.produce(job, a);
  p.produce(job, b);
  std::thread th([&] { p.produce(job, t); });
  th.join();
  CHECK(a.side == 68);  // T + 2B
  CHECK(a.channels == 4);
  REQUIRE(a.bytes == 68u * 68u * 4u);
  CHECK(std::memcmp(a.texels.get(), b.texels.get(), a.bytes) == 0);
  CHECK(std::memcmp(a.texels.get(), t.texels.get(), a.bytes) == 0);
  bool varied = false;
  for (std::size_t i = 4; i < a.bytes; i += 4) varied |= a.texels[i] != a.texels[0];
  CHECK(varied);  // brushes blended, not a flat fill
  // Another place: other bytes.
  TileData o;
  p.produce(tile_job(c, TileKey(0, 1, 6, 3)), o);
  CHECK(std::memcmp(a.texels.get(), o.texels.get(), a.bytes) != 0);

  // The coarsest level is one texel: composed into the slot's payload corner, the rest zero.
  TileData z;
  p.produce(tile_job(c, TileKey(0, 12, 0, 0)), z);
  REQUIRE(z.bytes == 68u * 68u * 4u);
  CHECK(z.texels[(2 * 68 + 2) * 4 + 3] == 255);  // the payload's texel (alpha of opaque brushes)
  CHECK(z.texels[3] == 0);                       // the border, not composed

  // Brush mips: served (not read), 4 · side² bytes, the root carrying its tail; the atlas's texels.
  TileJob bj;
  bj.key = TileKey(TerrainSystem::kBrushLayer, 0, 5, 2);
  CHECK(p.serves(bj));
  CHECK_FALSE(p.serves(job));
  TileData br;
  p.produce(bj, br);
  CHECK(br.bytes == 64u * 64u * 4u);
  const produce::Atlas& atlas = p.scene().atlas();
  CHECK(std::memcmp(br.texels.get() + 64 * 4 * 7, atlas.levels[0].texel(atlas.cols, 2, 0, 7), 64 * 4) == 0);
  bj.key = TileKey(TerrainSystem::kBrushLayer, 2, 5, 3);
  p.produce(bj, br);
  CHECK(br.bytes == (16u * 16 + 8 * 8 + 4 * 4 + 2 * 2 + 1) * 4u);
  CHECK(p.brush_bytes(2) == br.bytes);
  CHECK(p.tiles() == 5);
  CHECK(p.brushes() == 2);
}

// terrain.brush_files: the producer blends the images it names. Four solid brushes with no green:
// every composed texel has green 0 and opaque alpha, and varies with the masks (value noise has
// green everywhere); a brush mip is the file's texels. Files that do not fit are named.
TEST_CASE("terrain producer: brushes from image files (terrain.brush_files) are what it blends, and bad files are named") {
  test::RealScratch dir;
  const std::array<std::array<std::uint8_t, 3>, 4> colours = {{{255, 0, 0}, {0, 0, 255}, {128, 0, 128}, {200, 0, 50}}};
  const auto solid = [](int side, std::array<std::uint8_t, 3> rgb) {
    Image8 im;
    im.width = im.height = static_cast<std::uint64_t>(side);
    im.channels = 3;
    for (int t = 0; t < side * side; ++t) im.texels.insert(im.texels.end(), rgb.begin(), rgb.end());
    return im;
  };
  for (int i = 0; i < 4; ++i) write_image8(dir.file("b" + std::to_string(i) + ".png"), solid(64, colours[static_cast<std::size_t>(i)]));
  const ReplayConfig c = small_terrain({"terrain.brush_files=" + dir.file("b*.png")});
  const produce::TerrainProducerParams params = terrain_producer_params(c);
  REQUIRE(params.brush_files.size() == 1);
  produce::TerrainProducer p(params);
  TileData a;
  p.produce(tile_job(c, TileKey(0, 1, 5, 3)), a);
  REQUIRE(a.bytes == 64u * 64u * 4u);
  bool green = false, opaque = true, varied = false;
  for (std::size_t i = 0; i < a.bytes; i += 4) {
    green |= a.texels[i + 1] != 0;
    opaque &= a.texels[i + 3] == 255;
    varied |= a.texels[i] != a.texels[0];
  }
  CHECK_FALSE(green);
  CHECK(opaque);
  CHECK(varied);
  // The procedural brushes do have green: the files were used.
  produce::TerrainProducer noise(terrain_producer_params(small_terrain()));
  TileData n;
  noise.produce(tile_job(c, TileKey(0, 1, 5, 3)), n);
  bool noise_green = false;
  for (std::size_t i = 0; i < n.bytes; i += 4) noise_green |= n.texels[i + 1] != 0;
  CHECK(noise_green);
  // Brush 2's mip 1 (32², box-filtered from a solid image): its colour throughout.
  TileJob bj;
  bj.key = TileKey(TerrainSystem::kBrushLayer, 1, 0, 2);
  TileData br;
  p.produce(bj, br);
  REQUIRE(br.bytes == 32u * 32u * 4u);
  for (std::size_t i = 0; i < br.bytes; i += 4) {
    CHECK(br.texels[i] == 128);
    CHECK(br.texels[i + 1] == 0);
    CHECK(br.texels[i + 2] == 128);
    if (br.texels[i] != 128) break;
  }

  const auto refused = [&](const std::string& files, const std::string& what) {
    try {
      produce::TerrainProducer bad(terrain_producer_params(small_terrain({"terrain.brush_files=" + files})));
      FAIL("expected InputError");
    } catch (const InputError& e) {
      CAPTURE(e.what());
      CHECK(test::contains(e.what(), what));
    }
  };
  // Three images for four brushes a sector.
  refused(dir.file("b0.png") + ", " + dir.file("b1.png") + "," + dir.file("b2.png"),
          "field 'terrain.brush_files': 3 brush images for terrain.brushes_per_sector = 4");
  // A brush of another size than terrain.brush_size.
  write_image8(dir.file("small.png"), solid(32, colours[0]));
  refused(dir.file("b0.png") + "," + dir.file("b1.png") + "," + dir.file("b2.png") + "," + dir.file("small.png"),
          dir.file("small.png") + ": brush is 32×32; terrain.brush_size is 64");
  // Not square: named by the atlas builder before the size check.
  Image8 wide = solid(64, colours[0]);
  wide.height = 32;
  wide.texels.resize(64 * 32 * 3);
  write_image8(dir.file("wide.png"), wide);
  refused(dir.file("b0.png") + "," + dir.file("b1.png") + "," + dir.file("b2.png") + "," + dir.file("wide.png"), dir.file("wide.png"));
  // A missing file, a pattern that matches nothing, an empty name.
  refused(dir.file("b0.png") + "," + dir.file("b1.png") + "," + dir.file("b2.png") + "," + dir.file("gone.png"), dir.file("gone.png"));
  refused(dir.file("z*.png"), dir.file("z*.png") + ": no brush image matches this pattern");
  refused(dir.file("b0.png") + ",," + dir.file("b1.png"), "field 'terrain.brush_files': an empty name");
}

TEST_CASE("threaded executor without a store: production only, a read job and a missing producer refused") {
  ThreadedExecutorConfig xc;
  xc.capacity = 4;
  CHECK_THROWS_AS(ThreadedExecutor{xc}, std::invalid_argument);  // nothing could run
  const ReplayConfig c = small_terrain();
  produce::TerrainProducer p(terrain_producer_params(c));
  xc.producer = &p;
  xc.produce_workers = 2;
  ThreadedExecutor exec(xc);
  CHECK(exec.io_threads() == 0);
  CHECK(exec.decode_workers() == 0);
  CHECK_FALSE(exec.direct());
  TileJob read;
  read.id = 1;
  read.key = TileKey(0, 0, 0, 0);  // not produced, not a brush: it would be read
  CHECK_THROWS_AS(exec.submit(read), std::logic_error);
  TileJob brush;
  brush.id = 2;
  brush.key = TileKey(TerrainSystem::kBrushLayer, 1, 0, 1);
  brush.decoded_bytes = p.brush_bytes(1);
  TileJob tile = tile_job(c, TileKey(0, 2, 1, 1));
  tile.id = 3;
  exec.submit(brush);
  exec.submit(tile);
  REQUIRE(exec.wait_for_results(2, std::chrono::seconds(20)));
  std::vector<JobResult> out;
  exec.collect(exec.now(), out);
  REQUIRE(out.size() == 2);
  for (const JobResult& r : out) {
    CHECK(r.outcome == JobOutcome::ready);
    CHECK(r.bytes_read == 0);
    REQUIRE(r.data);
    CHECK(r.data->bytes == (r.id == 2 ? p.brush_bytes(1) : 64u * 64u * 4u));
  }
  exec.shutdown();
  CHECK(p.tiles() == 1);
  CHECK(p.brushes() == 1);
}

TEST_CASE("real clock, terrain: a short walk produces its tiles on the production threads, byte-exact in the VRAM arena") {
  // No footprints: which of them a tile shows depends on when a thread composed it (by design).
  const ReplayConfig c = small_terrain({"terrain.footprint_every_m=0"});
  const Trace walk = small_walk(1.5);
  auto scene = make_scene_from_config(c);
  RealClockOptions o;
  o.memory_limit_bytes = 1ULL << 30;
  const RealRun run = run_real_replay(c, walk, *scene, o);
  const nlohmann::json& s = run.result.summary;
  const nlohmann::json& rc = s["real_clock"];
  CHECK(s["clock"] == "real");
  CHECK(rc["io_threads"] == 0);
  CHECK(rc["decode_workers"] == 0);
  CHECK(rc["uploads_without_data"] == 0);
  CHECK(rc["failed_tiles"].empty());
  const nlohmann::json& pr = rc["producer"];
  CHECK(pr["produce_workers"] == 2);
  CHECK(pr["tiles_composed"].get<std::uint64_t>() > 21);  // more than the pyramid's 16 + 4 + 1 of levels 4-6
  CHECK(pr["brush_mips_served"].get<std::uint64_t>() > 0);
  CHECK(pr["brush_commits"].get<std::uint64_t>() > 0);
  CHECK(pr["decals_drawn"].get<std::uint64_t>() > 0);
  CHECK(s["produce"]["produced"].get<std::uint64_t>() > 0);
  CHECK(s["produce"]["production_ms"].get<double>() > 0);
  CHECK(rc["vram_arena"]["uploads"].get<std::uint64_t>() > 0);
  CHECK(s["resources"]["produce_ms_per_frame"]["max"].get<double>() > 0);

  // The first pyramid level (level 4, 256² texels: 4 × 4 tiles) is produced at the start and never
  // moves: each of its tiles in the arena is what the producer composes for that key with the same
  // static decals (16 of 1 m, drawn at this level's 0.25 m texels), and they show in some tiles.
  produce::TerrainProducer p(terrain_producer_params(c)), bare(terrain_producer_params(c));
  p.set_decals(std::make_shared<produce::DecalLayer>(produce::DecalLayerParams{
      c.terrain.sectors_x, c.terrain.sectors_y, c.terrain.sector_m, c.terrain.decals_static, c.terrain.decal_size_m,
      c.terrain.decal_seed, c.terrain.footprint_size_m}));
  int compared = 0, with_decals = 0;
  for (std::uint32_t y = 0; y < 4; ++y)
    for (std::uint32_t x = 0; x < 4; ++x) {
      const TileKey k(0, 4, x, y);
      const auto held = run.arena->peek(k);
      REQUIRE(held.size() == 64u * 64u * 4u);
      TileData d, b;
      p.produce(tile_job(c, k), d);
      bare.produce(tile_job(c, k), b);
      CHECK(std::memcmp(held.data(), d.texels.get(), d.bytes) == 0);
      with_decals += std::memcmp(d.texels.get(), b.texels.get(), d.bytes) != 0;
      ++compared;
    }
  CHECK(compared == 16);
  CHECK(with_decals > 0);
  CHECK(p.decals_drawn() > 0);
  CHECK(bare.decals_drawn() == 0);
}

TEST_CASE("vtsim replay --clock real, terrain: runs without a store, and names what it cannot run") {
  test::RealScratch dir;
  save_trace(small_walk(0.5), dir.file("t.csv"));
  std::string sets;
  for (const std::string& s : kSmallTerrain) sets += " --set " + s;
  const std::string common = " --trace " + dir.file("t.csv") + sets;
  auto r = test::run_cli(dir, "replay --clock real --json -q" + common);
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["real_clock"]["producer"]["tiles_composed"].get<std::uint64_t>() > 0);
  CHECK(j["produce"]["produced"].get<std::uint64_t>() > 0);

  r = test::run_cli(dir, "replay --clock real --store " + dir.file("none.vts") + common);
  CHECK(r.code == 2);
  CHECK(r.err.find("--store") != std::string::npos);
  CHECK(r.err.find("drop --store") != std::string::npos);
  r = test::run_cli(dir, "replay --clock real" + common + " --set texture.layers=albedo:bc7");
  CHECK(r.code == 2);
  CHECK(r.err.find("field 'texture.layers'") != std::string::npos);
  r = test::run_cli(dir, "replay --clock real" + common + " --set produce.workers=0");
  CHECK(r.code == 2);
  CHECK(r.err.find("field 'produce.workers'") != std::string::npos);
  // Brush images from files (four 64² brushes, one a sector); a size that does not fit: exit 2, named.
  Image8 im;
  im.width = im.height = 64;
  im.channels = 4;
  im.texels.assign(64 * 64 * 4, 200);
  for (int i = 0; i < 4; ++i) write_image8(dir.file("brush" + std::to_string(i) + ".png"), im);
  r = test::run_cli(dir, "replay --clock real --json -q" + common + " --set terrain.brush_files=" + dir.file("brush*.png"));
  REQUIRE(r.code == 0);
  CHECK(nlohmann::json::parse(r.out)["real_clock"]["producer"]["tiles_composed"].get<std::uint64_t>() > 0);
  r = test::run_cli(dir, "replay --clock real" + common + " --set terrain.brush_files=" + dir.file("brush*.png") + " --set terrain.brush_size=128");
  CHECK(r.code == 2);
  CHECK(r.err.find(dir.file("brush0.png") + ": brush is 64×64; terrain.brush_size is 128") != std::string::npos);
}

TEST_CASE("vtsim replay --produce-samples, then vtsim calibrate --samples: the replay's own tiles fit the [produce] keys") {
  test::RealScratch dir;
  save_trace(small_walk(0.5), dir.file("t.csv"));
  std::string sets;
  for (const std::string& s : kSmallTerrain) sets += " --set " + s;
  const std::string common = " --trace " + dir.file("t.csv") + sets;
  auto r = test::run_cli(dir, "replay --clock real --json -q --produce-samples " + dir.file("tiles.csv") + common);
  REQUIRE(r.code == 0);
  const std::uint64_t composed = nlohmann::json::parse(r.out)["real_clock"]["producer"]["tiles_composed"].get<std::uint64_t>();
  const std::vector<produce::ProducedTile> tiles = produce::read_produced_tiles_csv(dir.file("tiles.csv"));
  CHECK(tiles.size() == composed);  // one row a composed tile, none lost
  for (const produce::ProducedTile& t : tiles) {
    CHECK(t.work.layers == 4);  // kSmallTerrain's brushes_per_sector
    CHECK(t.wall_ns > 0);
  }
  r = test::run_cli(dir, "calibrate --samples " + dir.file("tiles.csv") + " --produce-workers 2 -o " + dir.file("p.toml"));
  REQUIRE(r.code == 0);
  const std::string prof = test::slurp(dir.file("p.toml"));
  CHECK(prof.find("every sample blends 4 layers: per_texel_ns folded") != std::string::npos);
  CHECK(prof.find("[produce]\nper_tile_us = ") != std::string::npos);
  CHECK(prof.find("per_texel_ns = 0\n") != std::string::npos);
  r = test::run_cli(dir, "replay --config " + dir.file("p.toml") + common + " -q");
  CHECK(r.code == 0);  // a config the simulated clock takes

  // What it cannot do, each named: exit 2.
  r = test::run_cli(dir, "replay -q --produce-samples " + dir.file("x.csv") + common);
  CHECK(r.code == 2);
  CHECK(r.err.find("--produce-samples: records the tiles the terrain's compositor makes in the real clock: needs --clock real") !=
        std::string::npos);
  r = test::run_cli(dir, "calibrate --samples " + dir.file("tiles.csv") + " --store x.vts");
  CHECK(r.code == 2);
  CHECK(r.err.find("--samples: fits the [produce] keys") != std::string::npos);
  r = test::run_cli(dir, "calibrate --produce --quick --cpu-time");
  CHECK(r.code == 2);
  CHECK(r.err.find("--cpu-time: applies to --samples") != std::string::npos);
  r = test::run_cli(dir, "calibrate --samples " + dir.file("t.csv"));
  CHECK(r.code == 2);
  CHECK(r.err.find(dir.file("t.csv") + ":1: header") != std::string::npos);
}

TEST_SUITE_END();

TEST_CASE("decal layer: footprints appended while threads read are seen as a growing prefix, counted and collected alike") {
  produce::DecalLayer layer(produce::DecalLayerParams{4, 4, 16.0, 64, 1.0, 3, 0.5});
  CHECK(layer.statics() == 64);
  // Static decals only: count over the whole terrain at a fine texel is all of them.
  CHECK(layer.count(0.01, 0, 0, 64, 64) == 64);
  CHECK(layer.count(2.0, 0, 0, 64, 64) == 0);  // 1 m decals under a 2 m texel: not drawn
  constexpr int kFootprints = 20000;
  std::atomic<bool> stop{false};
  std::atomic<int> bad{0};
  const auto reader = [&] {
    std::vector<produce::Decal> got;
    std::uint32_t last = 0;
    while (!stop.load(std::memory_order_acquire)) {
      // Footprints at x = 0.5 + i mod 50, y = 40.25, all in the strip y in [40, 40.5).
      const std::uint32_t n = layer.count(0.01, 0, 40.0, 64, 40.5);
      got.clear();
      layer.collect(0.01, 0, 40.0, 64, 40.5, got);
      if (n < last || got.size() < n) ++bad;
      for (const produce::Decal& d : got)  // a torn entry would not be a whole 0.5 m footprint or 1 m static decal
        if (!(d.y1_m > 40.0 && d.y0_m < 40.5) || !(d.x1_m - d.x0_m == 0.5 || d.x1_m - d.x0_m == 1.0)) ++bad;
      last = n;
    }
  };
  std::thread r1(reader), r2(reader);
  std::uint32_t static_in_strip = layer.count(0.01, 0, 40.0, 64, 40.5);
  for (int i = 0; i < kFootprints; ++i) CHECK(layer.add_footprint(0.5 + i % 50, 40.25));
  stop.store(true, std::memory_order_release);
  r1.join();
  r2.join();
  CHECK(bad.load() == 0);
  CHECK(layer.footprints() == kFootprints);
  CHECK(layer.count(0.01, 0, 40.0, 64, 40.5) == static_in_strip + kFootprints);
  // The texels they touch: what decal_span gives for each decal collected, summed (the strip is
  // 6400 x 50 texels of 1 cm; a footprint touches 50 x 50 of them, a static decal 100 x its rows).
  std::uint64_t texels = 0, expect = 0;
  CHECK(layer.count(0.01, 0, 40.0, 64, 40.5, texels) == static_in_strip + kFootprints);
  std::vector<produce::Decal> all;
  layer.collect(0.01, 0, 40.0, 64, 40.5, all);
  for (const produce::Decal& d : all) expect += produce::decal_span(d, 0.01, 0, 40.0, 6400, 50).texels();
  CHECK(texels == expect);
  CHECK(texels >= std::uint64_t{kFootprints} * 50 * 50);
}
