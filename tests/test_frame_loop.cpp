// The frame loop in steps (sim/run/frame_loop.h): one view feeding several streaming systems in
// lockstep gives each exactly what its replay alone gives (what a sweep over configs relies on).
#include <doctest/doctest.h>

#include <memory>
#include <set>
#include <utility>
#include <string>
#include <vector>

#include "core/error.h"
#include "replay_test_util.h"
#include "sim/run/frame_loop.h"
#include "sim/run/replay.h"
#include "sim/run/systems.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_transform.h"
#include "sim/view/gpu_model.h"
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

// `frames` poses at 60 Hz of one still camera over the plane, looking down 25 degrees.
Trace frame_loop_still_trace(int width, int height, int frames) {
  Trace t;
  t.image_width = width;
  t.image_height = height;
  for (int i = 0; i < frames; ++i) {
    Pose p;
    p.t_s = i / 60.0;
    p.pos_m = {100.0, 100.0, 20.0};
    p.q = yaw_pitch_quat(30.0, -25.0);
    t.poses.push_back(p);
  }
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
      // A feedback latency delays what the run reads, not the view: it shares the view too.
      {"scene.kind=town", "view.render_threads=0", "run.system=vt", "view.feedback_latency=2"},
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

TEST_CASE("frame loop: view.feedback_latency = k hands the runtime the feedback rendered k frames before") {
  // A still camera: every frame renders the same view, so a run whose runtime reads each frame's
  // feedback k frames late is the run without latency, k frames later. Pop-in is measured on the
  // current frame either way.
  const Trace t = frame_loop_still_trace(320, 180, 40);
  // No locked levels: the locked pages are requested at frame 0 whatever the feedback says.
  const ReplayConfig base = load_replay_config("", {"run.system=vt", "view.render_threads=0", "vt.locked_levels=0"});
  const auto scene = make_scene_from_config(base);
  const ReplayResult r0 = run_replay(base, t, *scene);
  const std::vector<FrameRow>& f0 = r0.metrics.frames();
  int first_upload = -1;
  for (const FrameRow& r : f0)
    if (r.uploads > 0 && first_upload < 0) first_upload = r.frame;
  REQUIRE(first_upload >= 0);
  for (int k : {1, 3}) {
    CAPTURE(k);
    ReplayConfig cfg = base;
    cfg.view.feedback_latency = k;
    const ReplayResult rk = run_replay(cfg, t, *scene);
    const std::vector<FrameRow>& fk = rk.metrics.frames();
    REQUIRE(fk.size() == f0.size());
    for (int f = 0; f < k; ++f) {  // nothing read back yet: nothing needed, everything blurry
      CHECK(fk[f].needs == 0);
      CHECK(fk[f].uploads == 0);
      CHECK(fk[f].blurry == fk[f].samples);
    }
    // One frame before the shifted first upload: nothing uploaded; at it: the same uploads.
    CHECK(fk[first_upload + k - 1].uploads == 0);
    CHECK(fk[first_upload + k].uploads == f0[first_upload].uploads);
    for (std::size_t f = static_cast<std::size_t>(k); f < fk.size(); ++f) {
      CAPTURE(f);
      const FrameRow& a = fk[f];
      const FrameRow& b = f0[f - static_cast<std::size_t>(k)];
      CHECK(a.samples == b.samples);
      CHECK(a.blurry == b.blurry);
      CHECK(a.uploads == b.uploads);
      CHECK(a.upload_bytes == b.upload_bytes);
      CHECK(a.disk_bytes == b.disk_bytes);
      CHECK(a.needs == b.needs);
      CHECK(a.live_requests == b.live_requests);
      CHECK(a.finest_needed == b.finest_needed);
    }
  }
}

TEST_CASE("frame loop: view.feedback_sampling = sequence renders frame f's feedback at the tile pixel of f, every frame") {
  // A still camera: with the middle pixel the plan renders frame 0 only; with the sequence every
  // frame, each the GPU model at that frame's pixel of the sequence, in the loop and ahead alike.
  const Trace t = frame_loop_still_trace(160, 90, 20);
  CHECK_THROWS_WITH_AS(load_replay_config("", {"view.feedback_sampling=sequence"}), doctest::Contains("view.feedback_sampling"),
                       InputError);
  CHECK_THROWS_WITH_AS(load_replay_config("", {"view.feedback_sampling=random", "view.lod_model=gpu"}),
                       doctest::Contains("view.feedback_sampling"), InputError);
  const ReplayConfig middle = load_replay_config("", {"run.system=vt", "view.lod_model=gpu", "view.render_threads=0"});
  ReplayConfig seq = middle;
  seq.view.feedback_sampling = "sequence";
  CHECK(plan_frames(middle, t).render_frames == std::vector<int>{0});
  const FramePlan plan = plan_frames(seq, t);
  CHECK(plan.render_frames.size() == 20u);

  const auto gpu = make_scene_from_config(seq);  // the plane, drawn with the GPU model (view.lod_model = gpu)
  std::set<std::pair<int, int>> offsets;
  for (int threads : {0, 2}) {
    CAPTURE(threads);
    ViewStream view(seq, plan, *gpu, 7, true, threads);
    for (int f = 0; f < plan.frames; ++f) {
      const FrameView& v = view.frame(f, true);
      REQUIRE(v.fresh);
      ViewParams p = view_params(seq.view);
      feedback_tile_offset(FeedbackSampling::sequence, f, seq.view.divisor, p.sample_ox, p.sample_oy);
      CHECK(feedback_params(seq.view, f).sample_ox == p.sample_ox);
      CHECK(feedback_params(seq.view, f).sample_oy == p.sample_oy);
      offsets.insert({p.sample_ox, p.sample_oy});
      ViewBuffer direct;
      render_gpu_model(*gpu, make_camera(t.poses[static_cast<std::size_t>(f)], t.image_width, t.image_height), p,
                       p.sample_ox, p.sample_oy, direct);
      REQUIRE(v.feedback->has_samples);
      REQUIRE(v.feedback->view.samples.size() == direct.samples.size());
      bool same = true;
      for (std::size_t i = 0; i < direct.samples.size(); ++i) {
        const ViewSample &a = v.feedback->view.samples[i], &b = direct.samples[i];
        same = same && a.u == b.u && a.v == b.v && a.lod == b.lod && a.pixel == b.pixel;
      }
      CHECK(same);
    }
  }
  CHECK(offsets.size() == 20u);  // 20 frames, 20 different pixels of the 8x8 tile

  // The whole replay: the same results with the feedback rendered ahead on worker threads.
  ReplayConfig ahead = seq;
  ahead.view.render_threads = 2;
  test::check_same_results(run_replay(seq, t, *gpu), run_replay(ahead, t, *gpu));
  CHECK(run_replay(seq, t, *gpu).summary["popin"].dump() != run_replay(middle, t, *gpu).summary["popin"].dump());
}
