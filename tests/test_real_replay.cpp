// Real-clock replays (src/sim/run/real_replay.h): the store decides the texture, a short replay
// completes with every needed tile resident and byte-exact in the VRAM arena, the simulated clock
// reads exactly the same tiles, faults are counted and never stall the frame loop, and the CLI
// (`vtsim replay --clock real`, `vtsim calibrate`) works end to end.
#include <doctest/doctest.h>

#include <set>

#include <map>

#include "real_test_util.h"
#include "core/host_memory.h"
#include "sim/run/real_replay.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_gen.h"
#include "stream/exec/calibrate.h"
#include "stream/store/store_generator.h"
#include "stream/exec/threaded_executor.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;

namespace {

// The small store is 1024² texels (32 m at 32 texels/m), tile 64: a 256-texel clipsize gives two
// stack levels (1024, 512) of 4 × 4 tiles over a pyramid of nine levels.
ReplayConfig bound_cfg(const TileStore& store, const std::vector<std::string>& sets = {}) {
  ReplayConfig c;
  for (const char* s : {"texture.texels_per_m=32", "clipmap.clipsize=256", "view.divisor=16"})
    apply_set(replay_config_table(), c, s);
  for (const std::string& s : sets) apply_set(replay_config_table(), c, s);
  validate(c);
  bind_store_texture(c, store);
  return c;
}

Trace still_trace(double seconds) {
  TraceGenParams g = default_gen_params("static");
  g.start_m = {16.0, 16.0};
  g.duration_s = seconds;
  g.image_width = 640;
  g.image_height = 360;
  return generate_trace(g);
}

// 24 m in 2 s across the small store: a texel window of 768 at level 0, many tiles in and out.
Trace fast_walk_trace() {
  TraceGenParams g = default_gen_params("walk");
  g.start_m = {4.0, 16.0};
  g.speed_mps = 12.0;
  g.duration_s = 2.0;
  g.image_width = 640;
  g.image_height = 360;
  return generate_trace(g);
}

// The simulated clock over the same store reads and uploads exactly what the real run did, and
// ends with the same residency on screen; summary[section][key] agrees too.
void check_sim_reads_the_same(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const TileStore& store,
                              const RealRun& run, const char* section, const char* key) {
  ReplayEnv env;
  env.sizer = store_sizer(store);
  const ReplayResult sim = run_replay(cfg, trace, scene, env);
  const auto& s = run.result.summary;
  CHECK(sim.summary["bandwidth"]["disk_read_bytes"] == s["bandwidth"]["disk_read_bytes"]);
  CHECK(sim.summary["bandwidth"]["uploads"] == s["bandwidth"]["uploads"]);
  CHECK(sim.summary[section][key] == s[section][key]);
  CHECK(sim.metrics.frames().back().blurry == run.result.metrics.frames().back().blurry);
  CHECK(sim.metrics.frames().back().deficit_sum == run.result.metrics.frames().back().deficit_sum);
}

}  // namespace

TEST_CASE("bind_store_texture: the texture comes from the store, and a disagreeing config is rejected naming the field") {
  const TileStore store = TileStore::open(test::small_store());
  ReplayConfig c = bound_cfg(store);
  CHECK(c.texture.width == 1024);
  CHECK(c.texture.height == 1024);
  CHECK(c.texture.tile_size == 64);
  CHECK(c.texture.border == 0);
  REQUIRE(c.texture.layers.specs.size() == 2);
  CHECK(c.texture.layers.specs[0].name == "albedo");
  CHECK(c.texture.layers.specs[0].format == "rgb8");
  CHECK(c.texture.layers.specs[1].name == "normal");
  CHECK(c.texture.layers.specs[0].compression_ratio > 1.5);  // zstd on terrain albedo
  const auto totals = store.totals();
  CHECK(c.texture.layers.specs[1].compression_ratio ==
        doctest::Approx(static_cast<double>(totals[1].decoded_bytes) / static_cast<double>(totals[1].stored_bytes)).epsilon(1e-3));

  auto reject = [&](const std::string& set, const std::string& field) {
    ReplayConfig bad;
    apply_set(replay_config_table(), bad, "clipmap.clipsize=256");
    apply_set(replay_config_table(), bad, set);
    validate(bad);
    try {
      bind_store_texture(bad, store);
      FAIL("accepted " << set);
    } catch (const InputError& e) {
      CHECK(std::string(e.what()).find(field) != std::string::npos);
      CHECK(std::string(e.what()).find("real-test-small") != std::string::npos);
    }
  };
  reject("texture.width=2048", "texture.width");
  reject("texture.tile_size=32", "texture.tile_size");
  reject("texture.layers=albedo:rgb8", "texture.layers");        // one layer, the store has two
  reject("texture.layers=albedo:rgb8,normal:rg8", "texture.layers");
  // Agreeing explicit values are fine.
  ReplayConfig ok;
  apply_set(replay_config_table(), ok, "texture.layers=albedo:rgb8,normal:rgb8");
  apply_set(replay_config_table(), ok, "texture.width=1024");
  apply_set(replay_config_table(), ok, "clipmap.clipsize=256");
  validate(ok);
  CHECK_NOTHROW(bind_store_texture(ok, store));
}

TEST_CASE("store sizer: disk bytes are the aligned reads, decoded bytes the tile, and nothing outside the store") {
  const TileStore store = TileStore::open(test::small_store());
  const TileSizer sizer = store_sizer(store);
  const TileKey k(1, 2, 2, 1);
  CHECK(sizer(k).disk_bytes == store.locate(k).read_bytes);
  CHECK(sizer(k).decoded_bytes == 64u * 64u * 3u);
  CHECK(sizer(TileKey(0, 0, 999, 0)).disk_bytes == 0);
}

TEST_CASE("apply_speed: the trace plays faster in both clocks, and a bad factor names --speed") {
  ReplayConfig c;
  Trace t = still_trace(1.0);
  const double last = t.poses.back().t_s;
  apply_speed(c, t, 4.0);
  CHECK(t.poses.back().t_s == doctest::Approx(last / 4));
  CHECK(c.run.fps == doctest::Approx(240.0));
  for (double bad : {0.0, -1.0, 5000.0}) {
    try {
      apply_speed(c, t, bad);
      FAIL("accepted " << bad);
    } catch (const InputError& e) {
      CHECK(std::string(e.what()).find("--speed") != std::string::npos);
    }
  }
}

TEST_CASE("real clock: a short replay completes with every needed tile resident, byte-exact in the VRAM arena") {
  const TileStore store = TileStore::open(test::small_store());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  const ReplayConfig cfg = bound_cfg(store, {"io.engine=" + std::string(engine_name(engine)), "io.queue_depth=8"});
  const Trace trace = still_trace(1.5);
  const auto scene = make_scene_from_config(cfg);
  RealRun run = run_real_replay(cfg, trace, *scene, store);
  const auto& s = run.result.summary;
  const auto& frames = run.result.metrics.frames();
  REQUIRE(frames.size() == trace.poses.size());
  // By the end nothing is missing and nothing is in flight (samples beyond the finest window
  // stay coarser than they want: that is the clipmap, checked against the simulated clock below).
  CHECK(frames.back().needs == 0);
  CHECK(frames.back().live_requests == 0);
  CHECK(frames.back().samples > 0);
  CHECK(s["clock"] == "real");
  CHECK(s["faults"]["faults"] == 0);
  // Every upload landed in the arena, and every tile the arena holds is the store's tile.
  const auto& arena = *run.arena;
  const std::uint64_t uploads = s["bandwidth"]["uploads"].get<std::uint64_t>();
  CHECK(uploads > 50);
  CHECK(arena.stats().uploads == uploads);
  CHECK(s["real_clock"]["uploads_without_data"] == 0);
  CHECK(s["real_clock"]["startup_s"].get<double>() > 0.0);  // set-up before frame 0, reported apart
  CHECK(s["real_clock"]["startup_s"].get<double>() < s["run"]["wall_s"].get<double>());
  std::uint64_t held = 0;
  for (TileKey k : test::all_keys(store)) {
    const auto got = arena.peek(k);
    if (got.empty()) continue;
    ++held;
    const auto want = test::decoded(store, k);
    REQUIRE(got.size() == want.size());
    CHECK(std::equal(want.begin(), want.end(), got.begin()));
  }
  CHECK(held == uploads - arena.stats().overwrites);
  // Each needed tile was read once: disk bytes are the sum of their aligned records.
  std::uint64_t want_bytes = 0;
  for (TileKey k : test::all_keys(store))
    if (!arena.peek(k).empty()) want_bytes += store.locate(k).read_bytes;
  CHECK(s["bandwidth"]["disk_read_bytes"].get<std::uint64_t>() == want_bytes);

  CHECK(s["real_clock"]["io_engine"] == std::string(engine_name(engine)));
  CHECK(s["real_clock"]["io_queue_depth"] == (engine == IoEngine::io_uring ? 8 : 1));
  CHECK(s["real_clock"]["io_engine_warning"] == "");
  check_sim_reads_the_same(cfg, trace, *scene, store, run, "cache", "requests");
  }
}

TEST_CASE("real clock: a moving camera streams, cancels and still ends consistent") {
  const TileStore store = TileStore::open(test::small_store());
  const ReplayConfig cfg = bound_cfg(store, {"upload.tiles_per_frame=4", "io.threads=2", "decode.workers=1"});
  const auto scene = make_scene_from_config(cfg);
  const RealRun run = run_real_replay(cfg, fast_walk_trace(), *scene, store);
  const auto& s = run.result.summary;
  CHECK(s["faults"]["faults"] == 0);
  CHECK(s["bandwidth"]["uploads"].get<std::uint64_t>() == run.arena->stats().uploads);
  CHECK(s["latency_ms"]["tiles"].get<std::uint64_t>() == run.arena->stats().uploads);
  std::uint64_t tiles = 0;
  for (const auto& row : run.result.metrics.frames()) {
    CHECK(row.uploads <= 4);
    tiles += row.uploads;
  }
  CHECK(tiles == s["bandwidth"]["uploads"].get<std::uint64_t>());
  for (TileKey k : test::all_keys(store)) {
    const auto got = run.arena->peek(k);
    if (got.empty()) continue;
    const auto want = test::decoded(store, k);
    CHECK(std::equal(want.begin(), want.end(), got.begin()));
  }
}

TEST_CASE("real clock with injected faults: retried or failed, every fault counted by kind, nothing crashes") {
  const TileStore store = TileStore::open(test::small_store());
  for (const IoEngine engine : test::io_engines_here()) {
  CAPTURE(engine_name(engine));
  const ReplayConfig cfg = bound_cfg(store, {"io.fault_rate=0.2", "io.fault.short_read_rate=0.1", "io.fault.checksum_rate=0.1",
                                             "io.fault.slow_rate=0.1", "io.fault.slow_ms=20", "io.max_retries=1",
                                             "io.retry_backoff_frames=1", "io.engine=" + std::string(engine_name(engine))});
  const auto scene = make_scene_from_config(cfg);
  const RealRun run = run_real_replay(cfg, still_trace(1.5), *scene, store);
  const auto& f = run.result.summary["faults"];
  const auto& inj = run.result.summary["real_clock"]["injected_faults"];
  CHECK(f["io_error"].get<std::uint64_t>() > 0);
  CHECK(f["short_read"].get<std::uint64_t>() > 0);
  CHECK(f["checksum"].get<std::uint64_t>() > 0);
  CHECK(f["faults"].get<std::uint64_t>() ==
        f["io_error"].get<std::uint64_t>() + f["short_read"].get<std::uint64_t>() + f["checksum"].get<std::uint64_t>());
  // Every injected failure that reached the pipeline was counted (a read cancelled in flight
  // can take its fault with it).
  CHECK(f["io_error"].get<std::uint64_t>() <= inj["io_error"].get<std::uint64_t>());
  CHECK(f["checksum"].get<std::uint64_t>() <= inj["checksum"].get<std::uint64_t>());
  CHECK(inj["slow"].get<std::uint64_t>() > 0);
  CHECK(f["retries"].get<std::uint64_t>() > 0);
  CHECK(run.arena->stats().uploads > 0);  // the healthy tiles still arrived
  for (TileKey k : test::all_keys(store)) {
    const auto got = run.arena->peek(k);
    if (got.empty()) continue;
    const auto want = test::decoded(store, k);
    CHECK(std::equal(want.begin(), want.end(), got.begin()));  // nothing corrupt reached VRAM
  }
  }
}

TEST_CASE("real clock: the summary names the tiles that failed (layer, level, x, y, reason), capped with a count") {
  const TileStore store = TileStore::open(test::small_store());
  const ReplayConfig cfg = bound_cfg(store, {"io.fault_rate=1", "io.max_retries=0"});  // every read fails
  const auto scene = make_scene_from_config(cfg);
  const RealRun run = run_real_replay(cfg, still_trace(0.5), *scene, store);
  const auto& rc = run.result.summary["real_clock"];
  const auto& failed = rc["failed_tiles"];
  const std::uint64_t failed_count = run.result.summary["faults"]["failed_tiles"].get<std::uint64_t>();
  REQUIRE(failed_count > 0);
  REQUIRE(!failed.empty());
  CHECK(failed.size() <= 50);
  const std::uint64_t named = failed.size() + rc["failed_tiles_not_listed"].get<std::uint64_t>();
  // Each failed tile is named once; a read whose fault arrived after its tile was no longer
  // needed is a fault, not a failed tile, so it can be named too (never more than the faults).
  CHECK(named >= failed_count);
  CHECK(named <= run.result.summary["faults"]["faults"].get<std::uint64_t>());
  for (const auto& t : failed) {
    CHECK(t["fault"] == "io_error");
    CHECK(!t["reason"].get<std::string>().empty());
    CHECK(t["attempts"].get<int>() >= 1);
    CHECK(store.contains(TileKey(t["layer"].get<std::uint32_t>(), t["level"].get<std::uint32_t>(), t["x"].get<std::int64_t>(),
                                 t["y"].get<std::int64_t>())));
  }
}

// Virtual texturing in the real clock: pages go to the slots the page pool chose (VramArena's pool
// layout). Every page complete in the pool at the end is in the arena at its own slot, every layer
// the store's bytes (what sampling through the page table would read); any other layer a slot holds
// is the store's too. Returns the layers the arena holds.
namespace {

std::uint64_t check_pool_arena(const RealRun& run, const TileStore& store, std::uint32_t slots, bool one_slot_per_page) {
  const VramArena& arena = *run.arena;
  REQUIRE(arena.pool());
  CHECK(run.result.summary["real_clock"]["vram_arena"]["pool_layers_missing"] == 0);
  CHECK(run.result.summary["real_clock"]["vram_arena"]["pool_pages_complete"] == run.pool_pages.size());
  for (const auto& [page, slot] : run.pool_pages)
    for (std::uint32_t layer = 0; layer < store.layer_count(); ++layer) {
      const TileKey k(layer, page.level(), page.x(), page.y());
      const auto got = arena.peek(k, slot);
      REQUIRE(!got.empty());
      const auto want = test::decoded(store, k);
      CHECK(std::equal(want.begin(), want.end(), got.begin(), got.end()));
    }
  std::uint64_t held = 0;
  for (TileKey k : test::all_keys(store)) {
    int in_slots = 0;
    for (std::uint32_t s = 0; s < slots; ++s) {
      const auto got = arena.peek(k, s);
      if (got.empty()) continue;
      ++held;
      ++in_slots;
      const auto want = test::decoded(store, k);
      CHECK(std::equal(want.begin(), want.end(), got.begin(), got.end()));
    }
    if (one_slot_per_page) CHECK(in_slots <= 1);
  }
  return held;
}

}  // namespace

TEST_CASE("real clock, virtual texturing: pages land byte-exact in their pool slots, and the simulated clock reads the same") {
  const TileStore store = TileStore::open(test::small_vt_store());
  const ReplayConfig cfg = bound_cfg(store, {"run.system=vt", "vt.pool_pages=64"});
  CHECK(cfg.texture.tile_size == 64);
  CHECK(cfg.texture.border == 4);  // pages stored 72² with their borders
  const Trace trace = still_trace(1.5);
  const auto scene = make_scene_from_config(cfg);
  const RealRun run = run_real_replay(cfg, trace, *scene, store);
  const auto& s = run.result.summary;
  const auto& frames = run.result.metrics.frames();
  REQUIRE(frames.size() == trace.poses.size());
  CHECK(s["system"] == "vt");
  CHECK(s["clock"] == "real");
  CHECK(frames.back().needs == 0);
  CHECK(frames.back().live_requests == 0);
  CHECK(frames.back().samples > 0);
  const std::uint64_t uploads = s["bandwidth"]["uploads"].get<std::uint64_t>();
  CHECK(uploads > 10);
  CHECK(uploads % 2 == 0);  // both layers of every page
  CHECK(s["real_clock"]["uploads_without_data"] == 0);
  CHECK(s["vt"]["vram_evictions"] == 0);
  const VramArena& arena = *run.arena;
  CHECK(arena.stats().uploads == uploads);
  CHECK(arena.stats().overwrites == 0);
  CHECK(arena.capacity_bytes() == 64u * (store.tile_bytes(0) + store.tile_bytes(1)));
  CHECK(check_pool_arena(run, store, 64, true) == uploads);
  CHECK(run.pool_pages.size() * 2 == uploads);  // every page uploaded is complete and in the pool
  CHECK(s["vt"]["layer_commits"].get<std::uint64_t>() == uploads);

  check_sim_reads_the_same(cfg, trace, *scene, store, run, "vt", "pages_mapped");
}

TEST_CASE("real clock, virtual texturing: an oversubscribed pool evicts and reuses slots, and VRAM stays the store's bytes") {
  const TileStore store = TileStore::open(test::small_vt_store());
  const ReplayConfig cfg = bound_cfg(store, {"run.system=vt", "vt.pool_pages=12", "upload.tiles_per_frame=4"});
  const auto scene = make_scene_from_config(cfg);
  const RealRun run = run_real_replay(cfg, fast_walk_trace(), *scene, store);
  const auto& s = run.result.summary;
  CHECK(s["faults"]["faults"] == 0);
  CHECK(s["vt"]["vram_evictions"].get<std::uint64_t>() > 0);
  CHECK(run.arena->stats().overwrites > 0);
  CHECK(run.arena->stats().uploads == s["bandwidth"]["uploads"].get<std::uint64_t>());
  for (const auto& row : run.result.metrics.frames()) CHECK(row.uploads <= 4);
  CHECK(run.pool_pages.size() > 0);
  CHECK(run.pool_pages.size() <= 12);
  // A partly overwritten slot keeps the evicted page's other layer: stale, but the store's bytes.
  CHECK(check_pool_arena(run, store, 12, false) >= 2 * run.pool_pages.size());
}

TEST_CASE("real clock, virtual texturing with injected faults: failed layers retried or given up, VRAM still exact") {
  const TileStore store = TileStore::open(test::small_vt_store());
  const ReplayConfig cfg = bound_cfg(store, {"run.system=vt", "vt.pool_pages=24", "io.fault_rate=0.3",
                                             "io.fault.checksum_rate=0.1", "io.fault.short_read_rate=0.1",
                                             "io.max_retries=1", "io.retry_backoff_frames=1"});
  const auto scene = make_scene_from_config(cfg);
  const RealRun run = run_real_replay(cfg, fast_walk_trace(), *scene, store);
  const auto& f = run.result.summary["faults"];
  CHECK(f["faults"].get<std::uint64_t>() > 0);
  CHECK(f["retries"].get<std::uint64_t>() > 0);
  CHECK(run.arena->stats().uploads > 0);
  CHECK(run.pool_pages.size() > 0);
  check_pool_arena(run, store, 24, false);  // no corrupt record reached VRAM, every mapped page whole
}

TEST_CASE("bind_store_texture, virtual texturing: pages with borders, every level down to one page, the field named") {
  const TileStore vt_store = TileStore::open(test::small_vt_store());
  // A bordered store is no clipmap texture (its windows keep neighbours adjacent).
  ReplayConfig clip;
  validate(clip);
  try {
    bind_store_texture(clip, vt_store);
    FAIL("a clipmap bound to a bordered store");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("texture.border") != std::string::npos);
  }
  // Levels 0..2 of a texture whose pages reach one page at level 4.
  test::RealScratch dir;
  GenOptions g;
  g.width = g.height = 1024;
  g.tile = 64;
  g.border = 4;
  g.levels = 3;
  g.layers = parse_gen_layers("albedo:zstd", "layers");
  generate_store(g, dir.file("three.vts"));
  const TileStore three = TileStore::open(dir.file("three.vts"));
  ReplayConfig vt;
  apply_set(replay_config_table(), vt, "run.system=vt");
  validate(vt);
  try {
    bind_store_texture(vt, three);
    FAIL("a virtual texture bound to a store without its coarse levels");
  } catch (const InputError& e) {
    const std::string m = e.what();
    CHECK(m.find("level_count") != std::string::npos);
    CHECK(m.find("single page (5)") != std::string::npos);
  }
  // The CLI end to end.
  REQUIRE(test::run_cli(dir, "trace gen static --duration 0.5 --start 16,16 --image 640x360 -o " + dir.file("t.csv")).code == 0);
  const auto r = test::run_cli(dir, "replay --clock real --system vt --store " + test::small_vt_store() + " --trace " +
                                        dir.file("t.csv") + " --set texture.texels_per_m=32 --json");
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["system"] == "vt");
  CHECK(j["clock"] == "real");
  CHECK(j["bandwidth"]["uploads"].get<int>() > 0);
}

TEST_CASE("VRAM arena: a pool arena places by slot, a window arena by key, and a wrong placement is refused") {
  const TileStore store = TileStore::open(test::small_vt_store());
  const std::uint32_t b0 = store.tile_bytes(0), b1 = store.tile_bytes(1);
  VramArena pool = VramArena::for_pool(3, {b0, b1});
  TileData t;
  t.key = TileKey(1, 0, 2, 3);
  t.bytes = b1;
  t.texels = std::make_unique<std::uint8_t[]>(b1);
  t.texels[0] = 42;
  pool.upload(t, 2);
  CHECK(pool.peek(t.key, 2).size() == b1);
  CHECK(pool.peek(t.key, 2)[0] == 42);
  CHECK(pool.peek(t.key, 1).empty());
  CHECK(pool.peek(TileKey(0, 0, 2, 3), 2).empty());  // the other layer of the slot is empty
  CHECK_THROWS_AS(pool.upload(t), std::invalid_argument);     // no slot
  CHECK_THROWS_AS(pool.upload(t, 3), std::invalid_argument);  // outside the pool
  pool.upload(t, 0);
  t.key = TileKey(1, 0, 0, 0);
  pool.upload(t, 2);
  CHECK(pool.stats().overwrites == 1);
  CHECK(pool.stats().uploads == 3);
  VramArena windows({{2, 2}}, {b0, b1});
  CHECK_THROWS_AS(windows.upload(t, 0), std::invalid_argument);  // placed by key
  windows.upload(t);
  CHECK(windows.peek(t.key).size() == b1);
}

TEST_CASE("VRAM arena: larger than the host's memory is refused before any allocation, at the exact byte") {
  const std::uint64_t tile = 1000 + 24 + 2 * 16;  // two layers, and 16 bytes of bookkeeping a slot
  CHECK(VramArena::for_pool(3, {1000, 24}, 3 * tile).capacity_bytes() == 3 * (1000 + 24));
  try {
    (void)VramArena::for_pool(3, {1000, 24}, 3 * tile - 1);
    FAIL("no ArenaTooLarge");
  } catch (const VramArena::ArenaTooLarge& e) {
    CHECK(e.bytes == 3 * tile);
    CHECK(e.limit == 3 * tile - 1);
  }
  CHECK_THROWS_AS(VramArena({{2, 2}, {1, 1}}, {1000, 24}, 5 * tile - 1), VramArena::ArenaTooLarge);
  // A window product that would overflow 64 bits is still a clean refusal.
  CHECK_THROWS_AS(VramArena({{std::int64_t{1} << 40, std::int64_t{1} << 40}}, {4096}), VramArena::ArenaTooLarge);
  CHECK(physical_memory_bytes() > (std::uint64_t{1} << 26));
  CHECK(usable_memory_bytes() <= physical_memory_bytes());
  CHECK_THROWS_AS(VramArena::for_pool(3, {1000, 0}), std::invalid_argument);  // a layer of no bytes
}

TEST_CASE("real clock: a page pool larger than the machine's memory is refused, naming vt.pool_pages") {
  // 2^24 pages of 72² texels in two layers: hundreds of GB, more than any test machine has. The
  // refusal comes before the allocation (under overcommit the allocation would succeed and zeroing
  // it would bring in the OOM killer; under ASan it would abort).
  const TileStore store = TileStore::open(test::small_vt_store());
  const std::uint64_t need = (std::uint64_t{1} << 24) * (store.tile_bytes(0) + store.tile_bytes(1));
  if (usable_memory_bytes() >= need) {
    MESSAGE("skipped: this process may use " << usable_memory_bytes() << " bytes, enough for the arena");
    return;
  }
  const ReplayConfig cfg = bound_cfg(store, {"run.system=vt", "vt.pool_pages=16777216"});
  const auto scene = make_scene_from_config(cfg);
  try {
    run_real_replay(cfg, still_trace(0.1), *scene, store);
    FAIL("a pool larger than host memory was allocated");
  } catch (const InputError& e) {
    const std::string w = e.what();
    CHECK(w.find("field 'vt.pool_pages': the VRAM arena needs") != std::string::npos);
    CHECK(w.find("memory this process may use") != std::string::npos);
  }
}

TEST_CASE("real clock: the RAM cache's buffers and the VRAM arena must fit in memory together, at the exact byte") {
  const TileStore store = TileStore::open(test::small_vt_store());
  const ReplayConfig cfg = bound_cfg(store, {"run.system=vt", "vt.pool_pages=64", "ram.capacity_MiB=1"});
  const auto scene = make_scene_from_config(cfg);
  const std::uint64_t page = store.tile_bytes(0) + store.tile_bytes(1);
  // What start-up reserves: the RAM cache's pages plus io.max_in_flight, and the pool's slots with
  // 16 bytes of bookkeeping a slot per layer.
  const std::uint64_t reserve = (std::uint64_t{1} << 20) / page * page + static_cast<std::uint64_t>(cfg.io.max_in_flight) * page;
  ThreadedExecutorConfig xc;
  xc.capacity = static_cast<std::size_t>(cfg.io.max_in_flight);
  xc.tile_memory_bytes = std::uint64_t{1} << 20;
  CHECK(ThreadedExecutor::reserved_pages(store, xc) * ThreadedExecutor::page_bytes(store) == reserve);
  const std::uint64_t arena = 64 * (page + 2 * 16);
  const auto error_at = [&](std::uint64_t limit) {
    RealClockOptions o;
    o.memory_limit_bytes = limit;
    try {
      run_real_replay(cfg, still_trace(0.05), *scene, store, o);
      return std::string();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
  };
  const std::string ram = error_at(reserve - 1);
  CHECK(ram.find("field 'ram.capacity_MiB': the RAM cache's buffers need") != std::string::npos);
  const std::string pool = error_at(reserve + arena - 1);
  CHECK(pool.find("field 'vt.pool_pages': the VRAM arena needs") != std::string::npos);
  CHECK(pool.find("less the RAM cache's buffers") != std::string::npos);
  CHECK(error_at(reserve + arena).empty());
}

TEST_CASE("real clock: the frame loop never waits for IO (every read takes 10 s, and the replay does not)") {
  const TileStore store = TileStore::open(test::small_store());
  const ReplayConfig cfg = bound_cfg(store, {"io.fault.slow_rate=1", "io.fault.slow_ms=10000"});
  const auto scene = make_scene_from_config(cfg);
  const auto t0 = std::chrono::steady_clock::now();
  const RealRun run = run_real_replay(cfg, still_trace(0.5), *scene, store);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  CHECK(wall < 5.0);  // 0.5 s of frames plus start-up and a prompt shutdown, far below one read
  CHECK(run.result.summary["bandwidth"]["uploads"] == 0);
  CHECK(run.result.metrics.frames().size() == 31);
  CHECK(run.result.metrics.frames().back().needs > 0);  // still waiting, not blocked
}

TEST_CASE("vtsim replay --clock real and vtsim calibrate: end to end, and the profile drives the simulated clock") {
  test::RealScratch dir;
  REQUIRE(test::run_cli(dir, "trace gen static --duration 0.5 --start 16,16 --image 640x360 -o " + dir.file("t.csv")).code == 0);
  const std::string common = " --store " + test::small_store() + " --trace " + dir.file("t.csv") +
                             " --set texture.texels_per_m=32 --set clipmap.clipsize=256";
  auto r = test::run_cli(dir, "replay --clock real" + common + " --summary " + dir.file("real.json"));
  CHECK(r.code == 0);
  CHECK(r.out.find("real clock") != std::string::npos);
  CHECK(r.err.find("texture from the store") != std::string::npos);
  r = test::run_cli(dir, "replay --clock real --trace " + dir.file("t.csv"));
  CHECK(r.code == 2);
  CHECK(r.err.find("--store") != std::string::npos);
  r = test::run_cli(dir, "replay --clock wall" + common);
  CHECK(r.code == 2);
  CHECK(r.err.find("--clock") != std::string::npos);
  // io_uring refused (as a kernel without it, or a seccomp filter, would): psync, with a warning
  // naming why; --werror makes that warning fail the run (exit 1).
  for (const char* err : {"ENOSYS", "EPERM"}) {
    CAPTURE(err);
    const std::string env = std::string("VTSIM_TEST_IO_URING_ERRNO=") + err + " ";
    const std::string args = " replay --clock real" + common + " --set io.engine=io_uring --summary " + dir.file("fb.json");
    r = test::run_capture(env + VTSIM_CLI + args + " 2>" + dir.file("stderr.txt"), dir.file("stderr.txt"));
    CHECK(r.code == 0);
    CHECK(r.err.find("io_uring_queue_init failed") != std::string::npos);
    CHECK(r.err.find(std::string(err) == "ENOSYS" ? "no io_uring" : "seccomp") != std::string::npos);
    CHECK(r.err.find("reading with psync") != std::string::npos);
    const auto fb = nlohmann::json::parse(test::slurp(dir.file("fb.json")));
    CHECK(fb["real_clock"]["io_engine"] == "psync");
    CHECK(fb["real_clock"]["io_engine_warning"].get<std::string>().find("io_uring_queue_init failed") != std::string::npos);
    r = test::run_capture(env + VTSIM_CLI + args + " --werror 2>" + dir.file("stderr.txt"), dir.file("stderr.txt"));
    CHECK(r.code == 1);
  }
  r = test::run_cli(dir, "replay --clock real" + common + " --set io.queue_depth=0");
  CHECK(r.code == 2);
  CHECK(r.err.find("io.queue_depth") != std::string::npos);
  r = test::run_cli(dir, "replay --clock real" + common + " --set io.engine=libaio");
  CHECK(r.code == 2);
  CHECK(r.err.find("io.engine") != std::string::npos);
  r = test::run_cli(dir, "replay --clock real --speed 0" + common);
  CHECK(r.code == 2);
  CHECK(r.err.find("--speed") != std::string::npos);

  r = test::run_cli(dir, "calibrate --quick --seconds 0.05 -q --store " + test::small_store() + " -o " + dir.file("p.toml"));
  REQUIRE(r.code == 0);
  const std::string prof = test::slurp(dir.file("p.toml"));
  CHECK(prof.find("[disk]") != std::string::npos);
  CHECK(prof.find("latency_us") != std::string::npos);
  r = test::run_cli(dir, "replay --clock sim --config " + dir.file("p.toml") + common + " --json");
  REQUIRE(r.code == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["clock"] == "simulated");
  CHECK(j["bandwidth"]["uploads"].get<int>() > 0);

  // io_uring (where the kernel allows it): depth points (io_threads threads x depth), a profile
  // with the engine and the depth.
  if (io_uring_unavailable().empty()) {
  r = test::run_cli(dir, "calibrate --quick --seconds 0.05 -q --io-threads 2 --engine io_uring --queue-depth 8 --json --store " +
                             test::small_store() + " -o " + dir.file("u.toml"));
  REQUIRE(r.code == 0);
  const auto cj = nlohmann::json::parse(r.out);
  std::set<int> depths;
  for (const auto& p : cj["reads"]) {
    depths.insert(p["depth"].get<int>());
    CHECK(p["concurrency"].get<int>() == 2 * p["depth"].get<int>());
    CHECK(p["MBps"].get<double>() > 0);
  }
  CHECK(depths == std::set<int>{1, 8});
  const std::string uprof = test::slurp(dir.file("u.toml"));
  CHECK(uprof.find("engine = \"io_uring\"") != std::string::npos);
  CHECK(uprof.find("queue_depth = 8") != std::string::npos);
  CHECK(cj["profile"]["disk.channels"] == 2);
  CHECK(cj["profile"]["disk.queue_depth"] == 8);
  r = test::run_cli(dir, "replay --clock sim --config " + dir.file("u.toml") + common + " --json");
  CHECK(r.code == 0);
  }
  r = test::run_cli(dir, "calibrate --quick -q --engine io_uring --queue-depth 0 --store " + test::small_store());
  CHECK(r.code == 2);
  CHECK(r.err.find("--queue-depth") != std::string::npos);
}

TEST_CASE("calibrate: one point per size and concurrency, a fitted model that reproduces the measured bandwidth") {
  const TileStore store = TileStore::open(test::small_store());
  CalibrateOptions o;
  o.io_threads = 2;
  o.decode_workers = 1;
  o.seconds_per_point = 0.05;
  o.sizes = {4096, 16384};
  o.concurrency = {1};
  o.decode_sample = 8;
  const Calibration c = calibrate(store, o);
  // sizes 4, 16 KiB and the store's mean read; concurrency 1 and io_threads.
  CHECK(c.reads.size() == (c.mean_read_bytes <= 16384 && static_cast<std::uint64_t>(c.mean_read_bytes) % 4096 == 0 ? 4u : 6u));
  for (const auto& p : c.reads) {
    CHECK(p.reads > 0);
    CHECK(p.MBps > 0);
    CHECK(p.p50_us <= p.p95_us);
    CHECK(p.p95_us <= p.p99_us);
  }
  CHECK(c.disk.channels == 2);
  CHECK(c.disk.latency_us >= 0);
  CHECK(c.disk.bandwidth_MBps > 0);
  CHECK(c.decode.workers == 1);
  CHECK(c.decode.per_tile_us > 0);
  CalibrateOptions bad;
  bad.sizes = {1000};
  CHECK_THROWS_AS(calibrate(store, bad), InputError);
}

TEST_CASE("fit_disk_model recovers the latency and bandwidth of a device that follows the model") {
  const DiskModel truth{120.0, 900.0, 4};
  std::vector<ReadPoint> pts;
  for (std::uint32_t bytes : {4096u, 16384u, 49152u, 262144u})
    for (int c : {1, 2, 4, 8}) {
      ReadPoint p;
      p.bytes = bytes;
      p.concurrency = c;
      p.MBps = disk_throughput_Bps(DiskModel{truth.latency_us, truth.bandwidth_MBps, c}, bytes) / 1e6;
      pts.push_back(p);
    }
  std::vector<std::string> notes;
  const DiskModel m = fit_disk_model(pts, 4, 49152, &notes);
  CHECK(m.latency_us == doctest::Approx(120.0).epsilon(0.01));
  CHECK(m.bandwidth_MBps == doctest::Approx(900.0).epsilon(0.01));
  CHECK(m.channels == 4);
  REQUIRE(notes.size() == 1);
  CHECK(notes[0].find("48K×4 +0%") != std::string::npos);
  // Concurrency beyond io_threads is not the pool's operating range: those points are ignored.
  for (auto& p : pts)
    if (p.concurrency == 8) p.MBps *= 5;
  const DiskModel m2 = fit_disk_model(pts, 4, 49152);
  CHECK(m2.latency_us == doctest::Approx(120.0).epsilon(0.01));
  CHECK_THROWS_AS(fit_disk_model({}, 4, 4096), std::invalid_argument);
}

TEST_SUITE_END();
