// The frame loop in steps (sim/run/frame_loop.h): one view feeding several streaming systems in
// lockstep gives each exactly what its replay alone gives (what a sweep over configs relies on).
#include <doctest/doctest.h>

#include <memory>
#include <string>
#include <vector>

#include "core/error.h"
#include "replay_test_util.h"
#include "sim/run/frame_loop.h"
#include "sim/run/replay.h"
#include "sim/run/systems.h"
#include "sim/trace/trace_io.h"
#include "sim/view/scene.h"
#include "stream/system/i_system.h"
#include "test_util.h"

using namespace vtsim;

namespace {

// The first `seconds` of the checked-in town walk.
Trace town_walk_prefix(double seconds) {
  Trace t = load_trace(test::kData + "/town_walk.csv");
  while (!t.poses.empty() && t.poses.back().t_s > seconds) t.poses.pop_back();
  return t;
}

}  // namespace

TEST_CASE("frame loop: systems stepped on one view each give exactly their replay alone") {
  const Trace walk = town_walk_prefix(4.0);
  // Configs that share the view ([view], scene, tile size, run.fps) and differ in everything else:
  // the system, the policy, the budgets, the devices, a feedback bias that reads every sample.
  const std::vector<std::vector<std::string>> sets = {
      {"scene.kind=town", "view.render_threads=0"},
      {"scene.kind=town", "view.render_threads=0", "throttle.policy=none", "upload.tiles_per_frame=4", "disk.preset=hdd"},
      {"scene.kind=town", "view.render_threads=0", "run.system=vt", "vt.pool_pages=96", "throttle.policy=unreal_bias"},
      {"scene.kind=town", "view.render_threads=0", "run.system=vt", "vt.pool_pages=400", "ram.capacity_MiB=8"},
  };
  std::vector<ReplayConfig> cfgs;
  for (const auto& s : sets) cfgs.push_back(load_replay_config("", s));
  const auto scene = make_scene_from_config(cfgs[0]);

  std::vector<ReplayResult> alone;
  for (const ReplayConfig& c : cfgs) alone.push_back(run_replay(c, walk, *scene));

  const FramePlan plan = plan_frames(cfgs[0], walk);
  const ReplayEnv env;
  std::vector<std::unique_ptr<SystemRun>> runs;
  bool keep = false;
  for (const ReplayConfig& c : cfgs) {
    runs.push_back(std::make_unique<SystemRun>(c, plan, *scene, env));
    REQUIRE(runs.back()->block_shift() == runs.front()->block_shift());  // one view: one span granularity
    keep = keep || !runs.back()->system().uses_spans();
  }
  ViewStream view(cfgs[0], plan, *scene, runs.front()->block_shift(), keep, 0);
  for (int f = 0; f < plan.frames; ++f) {
    bool any_keep = false;
    for (auto& r : runs) {
      r->begin_frame(f, plan.target(f));
      any_keep = any_keep || r->keep_samples();
    }
    const FrameView& v = view.frame(f, any_keep);
    for (auto& r : runs) r->step(v);
  }
  for (std::size_t i = 0; i < runs.size(); ++i) {
    CAPTURE(i);
    test::check_same_results(runs[i]->summarize(RunCost{}), alone[i]);
  }
  // The configs did differ: the systems' results are not all the same.
  CHECK(alone[0].summary["bandwidth"].dump() != alone[1].summary["bandwidth"].dump());
  CHECK(alone[2].summary["vt"].dump() != alone[3].summary["vt"].dump());
}

TEST_CASE("frame loop: the plan renders every feedback_every-th frame whose pose moved, and measures those frames") {
  Trace t;
  for (int i = 0; i < 12; ++i) {
    Pose p;
    p.t_s = i / 60.0;
    p.pos_m = {100.0 + (i < 6 ? i : 5), 100.0, 2.0};  // moves for 6 frames, then stands still
    t.poses.push_back(p);
  }
  ReplayConfig cfg;
  cfg.view.feedback_every = 2;
  cfg.run.fps = 0;  // the trace's own times
  const FramePlan plan = plan_frames(cfg, t);
  CHECK(plan.frames == 12);
  CHECK(plan.render_frames == std::vector<int>{0, 2, 4, 6});  // 8 and 10 repeat 6's pose
  for (int f = 0; f < 12; ++f) CHECK(plan.measured(f) == (f % 2 == 0));
  CHECK(plan.period_s == doctest::Approx(1.0 / 60.0));
  CHECK(plan.duration_s == doctest::Approx(12.0 / 60.0));
  CHECK(plan.target(3) == seconds_to_ticks(3.0 / 60.0));
  CHECK_THROWS_AS(plan_frames(cfg, Trace{}), InputError);
}
