// The tile timeline in the real clock (`vtsim replay --clock real --timeline`): IO and decode
// threads on a small store, wall times; the file is valid Trace Event JSON and counts what the
// summary counts.
#include <doctest/doctest.h>

#include <map>
#include <nlohmann/json.hpp>

#include "real_test_util.h"
#include "sim/run/real_replay.h"
#include "sim/run/timeline.h"
#include "sim/trace/trace_gen.h"
#include "sim/view/scene.h"
#include "stream/store/tile_store.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;

TEST_CASE("timeline, real clock: a short replay on IO and decode threads writes a valid timeline with wall times") {
  const TileStore store = TileStore::open(test::small_store());
  ReplayConfig cfg;
  for (const char* s : {"texture.texels_per_m=32", "clipmap.clipsize=256", "view.divisor=16", "upload.tiles_per_frame=8",
                        "io.threads=2", "decode.workers=1"})
    apply_set(replay_config_table(), cfg, s);
  validate(cfg);
  bind_store_texture(cfg, store);
  TraceGenParams g = default_gen_params("walk");
  g.start_m = {8.0, 16.0};
  g.speed_mps = 6.0;
  g.duration_s = 0.5;
  g.image_width = 640;
  g.image_height = 360;
  const Trace trace = generate_trace(g);
  const auto scene = make_scene_from_config(cfg);
  TimelineRecorder tl;
  RealClockOptions ro;
  ro.timeline = &tl;
  const RealRun run = run_real_replay(cfg, trace, *scene, store, ro);
  const auto& s = run.result.summary;
  const nlohmann::json j = nlohmann::json::parse(tl.json());
  CHECK(j["otherData"]["clock"] == "real");
  std::map<std::string, std::uint64_t> n;
  double last_ts = 0;
  for (const auto& e : j["traceEvents"]) {
    if (e["ph"] == "M") continue;
    ++n[e["name"].get<std::string>()];
    last_ts = std::max(last_ts, e["ts"].get<double>());
  }
  CHECK(n["request"] == s["cache"]["requests"].get<std::uint64_t>());
  CHECK(n["read"] == s["bandwidth"]["disk_reads"].get<std::uint64_t>());
  CHECK(n["upload"] == s["bandwidth"]["uploads"].get<std::uint64_t>());
  CHECK(n["evicted"] == s["cache"]["vram_evictions"].get<std::uint64_t>());
  CHECK(n["upload"] > 0);
  CHECK(n["first sampled"] > 0);
  // Wall times: the last event lies within the run's wall time (µs), after its first frames.
  CHECK(last_ts > 0.0);
  CHECK(last_ts <= s["run"]["wall_s"].get<double>() * 1e6 + 1e6);
}

TEST_SUITE_END();
