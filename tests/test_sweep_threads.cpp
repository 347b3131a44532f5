// The sweep's threads (doctest suite "threads", run under TSan): a team of threads stepping the
// runs of one view while render-ahead renders, and tasks on a pool, give the one-thread results.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "sim/run/replay.h"
#include "sim/sweep/lockstep.h"
#include "sim/sweep/sweep.h"
#include "sim/sweep/tune.h"
#include "sim/trace/trace_io.h"
#include "sim/view/scene.h"
#include "real_test_util.h"
#include "store_test_util.h"
#include "test_util.h"

using namespace vtsim;

TEST_SUITE_BEGIN("threads");

TEST_CASE("sweep threads: a stepping team and render-ahead give the one-thread rows") {
  Trace walk = load_trace(test::kData + "/town_walk.csv");
  while (!walk.poses.empty() && walk.poses.back().t_s > 1.0) walk.poses.pop_back();
  std::vector<ReplayConfig> cfgs;
  for (const char* extra : {"throttle.policy=none", "run.system=vt", "throttle.policy=unreal_bias", "upload.tiles_per_frame=2"}) {
    std::vector<std::string> sets = {"scene.kind=town", "view.divisor=16", extra};
    if (std::string(extra) == "throttle.policy=unreal_bias") sets.insert(sets.end(), {"run.system=vt", "vt.pool_pages=64"});
    cfgs.push_back(load_replay_config("", sets));
  }
  std::vector<const ReplayConfig*> ptrs;
  for (const auto& c : cfgs) ptrs.push_back(&c);
  const auto scene = make_scene_from_config(cfgs[0]);
  const auto one = run_lockstep(ptrs, walk, *scene, 1);
  const auto three = run_lockstep(ptrs, walk, *scene, 3);
  for (std::size_t i = 0; i < cfgs.size(); ++i) {
    CAPTURE(i);
    REQUIRE(one[i].ok);
    REQUIRE(three[i].ok);
    CHECK(one[i].summary.dump() == three[i].summary.dump());
  }
}

TEST_CASE("sweep threads: tasks on a pool of threads write the same outputs as one thread") {
  test::TempDir d;
  std::ofstream(d.file("spec.toml")) << "set = [\"view.divisor=32\"]\ngenerate = [\"walk duration_s=1\", \"turn duration_s=1 "
                                        "event_s=0.5\"]\n[grid]\n\"upload.tiles_per_frame\" = [2, -1]\n";
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  SweepOptions a, b;
  a.out_dir = d.file("a");
  a.jobs = 1;
  b.out_dir = d.file("b");
  b.jobs = 3;
  b.progress = [](std::size_t, std::size_t, double, double, double) {};
  run_sweep(spec, a);
  run_sweep(spec, b);
  CHECK(test::slurp(a.out_dir + "/rows.jsonl") == test::slurp(b.out_dir + "/rows.jsonl"));
}

TEST_SUITE_END();

TEST_CASE("sweep threads: tune's real-clock check replays a config in both clocks on a store and reports each gap") {
  test::TempDir d;
  std::ofstream(d.file("spec.toml")) << R"(set = ["texture.texels_per_m=32", "clipmap.clipsize=256", "view.divisor=16"]
generate = ["static duration_s=1 start_m=16,16 image=640x360"]
[grid]
"upload.tiles_per_frame" = [1, 4]
[tune]
constraints = ["latency_ms.p99 <= 10000", "bandwidth.uploads >= 1"]
)";
  const SweepSpec spec = load_sweep_spec(d.file("spec.toml"));
  const nlohmann::json r = tune_real_check(spec, load_sweep_traces(spec), 1, test::small_store());
  CHECK(r["config"] == 1);
  CHECK(r["sim_pass"] == true);
  CHECK(r["real_pass"] == true);
  REQUIRE(r["constraints"].size() == 2);
  // The simulated clock on the store's tile sizes reads what the real clock read (a still camera).
  CHECK(r["constraints"][1]["sim"] == r["constraints"][1]["real"]);
  CHECK(r["constraints"][1]["gap"] == 0.0);
}

TEST_CASE("sweep threads: tune refuses a store that fits no config of the grid before any replay") {
  test::TempDir d;
  std::ofstream(d.file("spec.toml")) << R"(set = ["texture.tile_size=32"]
generate = ["walk duration_s=1"]
[grid]
"upload.tiles_per_frame" = [1, 4]
[tune]
constraints = ["latency_ms.p99 <= 10000"]
)";
  const test::CliRun r = test::run_vtsim_capture("tune " + d.file("spec.toml") + " -o " + d.file("out") + " --store " +
                                                     test::small_store(), d.file("err"));
  CHECK(r.code == 2);
  CHECK(test::contains(r.err, "fits no config of the grid (config 0: "));
  CHECK(test::contains(r.err, "texture.tile_size"));
  CHECK_FALSE(std::filesystem::exists(d.file("out")));
}
