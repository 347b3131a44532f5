// The streaming runtime an engine calls (stream/runtime/streaming_runtime.h) in the simulated
// clock: an engine-like loop with a fake GPU ends with the residency and uploads of the replay on
// the same input, for both systems; the page-table and window updates describe the residency;
// requests stream what they name; bad calls are refused naming the call; an upload that throws
// loses nothing.
#include <doctest/doctest.h>

#include <bit>
#include <glm/geometric.hpp>
#include <set>
#include <string>

#include "core/camera.h"
#include "runtime_test_util.h"
#include "sim/run/replay.h"
#include "sim/run/runtime_setup.h"
#include "sim/trace/trace_gen.h"
#include "sim/view/scene.h"
#include "stream/system/i_system.h"

using namespace vtsim;

namespace {

ReplayConfig runtime_cfg(const char* system, const std::vector<std::string>& sets = {}) {
  std::vector<std::string> all = {"view.divisor=16"};
  all.insert(all.end(), sets.begin(), sets.end());
  return load_replay_config("", all, system);
}

Trace runtime_walk(double seconds) {
  TraceGenParams p = default_gen_params("walk");
  p.duration_s = seconds;
  p.image_width = 640;
  p.image_height = 360;
  return generate_trace(p);
}

struct EngineRun {
  std::uint64_t uploads = 0;
  std::vector<std::pair<TileKey, std::uint32_t>> pool_pages;  // the system's, at the end
  test::FakeGpu gpu{1, 0, 0};
  std::vector<ClipWindow> windows;  // the system's, at the end
};

// An engine's frame loop on the simulated clock: the feedback of each frame (vtsim's renderer,
// as the replay renders it), the camera with its velocity and cuts, end_frame into a fake GPU.
EngineRun engine_loop(const ReplayConfig& cfg, const Trace& trace, int throw_at_frame = -1) {
  auto scene = make_scene_from_config(cfg);
  const FramePlan plan = plan_frames(cfg, trace);
  StreamingRuntime rt(runtime_parts(cfg, scene->texture(), plan.period_s, nullptr, nullptr));
  ViewStream view(cfg, plan, *scene, std::bit_width(static_cast<unsigned>(cfg.texture.tile_size)) - 1, !rt.system().uses_spans(), 0);
  EngineRun run;
  run.gpu = test::FakeGpu(static_cast<int>(cfg.texture.layers.specs.size()), cfg.vt.pool_pages, 0);
  for (int f = 0; f < plan.frames; ++f) {
    rt.begin_frame(plan.target(f));
    const FrameView& v = view.frame(f, !rt.system().uses_spans() || rt.system().wants_samples());
    // The camera's velocity; a jump longer than metrics.cut_m is a cut (as the replay's).
    glm::dvec3 vel(0.0);
    bool cut = f == 0;
    if (f > 0) {
      const Pose& a = plan.trace.poses[static_cast<std::size_t>(f - 1)];
      const glm::dvec3 d = v.pose->pos_m - a.pos_m;
      cut = glm::length(d) > cfg.metrics.cut_m;
      if (!cut && v.pose->t_s > a.t_s) vel = d / (v.pose->t_s - a.t_s);
    }
    rt.set_camera(*v.pose, vel, cut);
    rt.set_feedback(*v.feedback, v.fresh);
    if (f == throw_at_frame) {
      run.gpu.throw_next(1);
      CHECK_THROWS_WITH_AS(rt.end_frame(run.gpu), doctest::Contains("StreamingRuntime::end_frame: the upload callback threw"),
                           RuntimeCallError);
      continue;
    }
    run.gpu.apply(rt.end_frame(run.gpu));
  }
  run.uploads = run.gpu.uploads;
  rt.system().pool_pages(run.pool_pages);
  rt.system().clip_windows(run.windows);
  return run;
}

}  // namespace

TEST_CASE("runtime: an engine's loop on the simulated clock ends as the replay does (vt), its page table as the pool's") {
  const ReplayConfig cfg = runtime_cfg("vt", {"vt.pool_pages=256"});
  const Trace trace = runtime_walk(1.5);
  const EngineRun run = engine_loop(cfg, trace);
  auto scene = make_scene_from_config(cfg);
  std::vector<std::pair<TileKey, std::uint32_t>> replay_pages;
  ReplayEnv env;
  env.on_finish = [&](const IStreamingSystem& s) { s.pool_pages(replay_pages); };
  const ReplayResult r = run_replay(cfg, trace, *scene, env);
  CHECK(run.uploads == r.summary["bandwidth"]["uploads"].get<std::uint64_t>());
  CHECK(run.uploads > 50);
  REQUIRE(!run.pool_pages.empty());
  CHECK(run.pool_pages == replay_pages);
  // The page table the updates built maps exactly the pool's complete pages, each at its slot.
  std::map<TileKey, std::int64_t> want;
  for (const auto& [page, slot] : run.pool_pages) want[page] = slot;
  CHECK(run.gpu.page_table == want);
  CHECK(run.windows.empty());
}

TEST_CASE("runtime: an engine's loop on the simulated clock ends as the replay does (clipmap), its windows as the clip stack's") {
  const ReplayConfig cfg = runtime_cfg("clipmap");
  const Trace trace = runtime_walk(1.5);
  const EngineRun run = engine_loop(cfg, trace);
  auto scene = make_scene_from_config(cfg);
  const ReplayResult r = run_replay(cfg, trace, *scene);
  CHECK(run.uploads == r.summary["bandwidth"]["uploads"].get<std::uint64_t>());
  CHECK(run.uploads > 100);
  REQUIRE(!run.windows.empty());
  REQUIRE(run.gpu.windows.size() == run.windows.size());
  for (std::size_t l = 0; l < run.windows.size(); ++l) {
    CAPTURE(l);
    CHECK(run.gpu.windows.at(static_cast<int>(l)) == run.windows[l]);
  }
  CHECK(run.gpu.page_table.empty());
}

TEST_CASE("runtime: an upload that throws loses nothing: the tile is queued again and uploaded on a later frame") {
  const ReplayConfig cfg = runtime_cfg("vt", {"vt.pool_pages=256"});
  const Trace trace = runtime_walk(1.0);
  const EngineRun clean = engine_loop(cfg, trace);
  // Find a frame with uploads, then make the first upload of that frame throw.
  auto scene = make_scene_from_config(cfg);
  const ReplayResult r = run_replay(cfg, trace, *scene);
  int at = -1;
  for (const FrameRow& row : r.metrics.frames())
    if (row.frame > 5 && row.uploads > 2) {
      at = row.frame;
      break;
    }
  REQUIRE(at > 0);
  const EngineRun failed = engine_loop(cfg, trace, at);
  REQUIRE(failed.gpu.thrown() == 1);
  // The tile whose copy threw is uploaded after the throw.
  const auto& up = failed.gpu.uploaded;
  CHECK(std::find(up.begin() + static_cast<std::ptrdiff_t>(failed.gpu.thrown_at_upload()), up.end(), failed.gpu.thrown_key()) != up.end());
  // Every tile the clean run uploaded is uploaded by the failing run too (later, not lost).
  const std::set<TileKey> a(clean.gpu.uploaded.begin(), clean.gpu.uploaded.end());
  const std::set<TileKey> b(failed.gpu.uploaded.begin(), failed.gpu.uploaded.end());
  CHECK(a == b);
  CHECK(failed.pool_pages == clean.pool_pages);
}

TEST_CASE("runtime: requests stream the pages they name and the updates map them") {
  const ReplayConfig cfg = runtime_cfg("vt", {"vt.pool_pages=64"});
  auto scene = make_scene_from_config(cfg);
  StreamingRuntime rt(runtime_parts(cfg, scene->texture(), 1.0 / 60, nullptr, nullptr));
  test::FakeGpu gpu(static_cast<int>(cfg.texture.layers.specs.size()), 64, 0);
  const std::vector<TileKey> want = {TileKey(0, 3, 10, 12), TileKey(0, 3, 11, 12), TileKey(0, 5, 2, 3)};
  for (int f = 0; f < 30; ++f) {
    rt.begin_frame(seconds_to_ticks(f / 60.0));
    for (const TileKey& k : want) rt.request(k);
    gpu.apply(rt.end_frame(gpu));
  }
  CHECK(rt.needs() == 0);
  for (const TileKey& k : want) {
    CAPTURE(k.level());
    CHECK(gpu.page_table.contains(k));
    // And every coarser ancestor (the fallback chain).
    for (std::uint32_t l = k.level() + 1; l < static_cast<std::uint32_t>(rt.system().num_levels()); ++l) {
      const TileKey p(0, l, k.x() >> (l - k.level()), k.y() >> (l - k.level()));
      CHECK(gpu.page_table.contains(p));
    }
  }
  // What the runtime asked the pool for and nothing more: 3 + their ancestors + the locked level.
  CHECK(gpu.page_table.size() < 40);
}

TEST_CASE("runtime: bad calls are refused with an exception naming the call") {
  const ReplayConfig cfg = runtime_cfg("vt", {"vt.pool_pages=64"});
  auto scene = make_scene_from_config(cfg);
  StreamingRuntime rt(runtime_parts(cfg, scene->texture(), 1.0 / 60, nullptr, nullptr));
  test::FakeGpu gpu(1, 64, 0);
  const auto call_of = [](auto&& fn) -> std::string {
    try {
      fn();
    } catch (const RuntimeCallError& e) {
      return e.call() + " | " + e.what();
    }
    return "no exception";
  };
  // Out of order: nothing begun.
  CHECK(call_of([&] { rt.request(TileKey(0, 0, 0, 0)); }).starts_with("request | StreamingRuntime::request: no frame is begun"));
  CHECK(call_of([&] { rt.end_frame(gpu); }).starts_with("end_frame |"));
  rt.begin_frame(0);
  // A frame begun twice.
  CHECK(call_of([&] { rt.begin_frame(1); }).starts_with("begin_frame | StreamingRuntime::begin_frame: frame 0 is begun and not ended"));
  // Keys outside the texture: 2^20 texels of 128-texel pages, 14 levels.
  const int n = rt.system().num_levels();
  CHECK(call_of([&] { rt.request(TileKey(0, 0, 8192, 0)); }).find("outside the texture: level 0 is 8192×8192 tiles") != std::string::npos);
  CHECK(call_of([&] { rt.request(TileKey(0, 4, 0, 512)); }).find("level 4 is 512×512 tiles") != std::string::npos);
  CHECK(call_of([&] { rt.request(TileKey(0, static_cast<std::uint32_t>(n), 0, 0)); }).find("levels") != std::string::npos);
  CHECK(call_of([&] { rt.request(TileKey(5, 0, 0, 0)); }).find("layer(s)") != std::string::npos);
  rt.request(TileKey(0, 0, 8191, 8191));  // the last tile is inside
  rt.end_frame(gpu);
  // A span buffer that cannot give its samples; one kind of feedback a frame.
  rt.begin_frame(5);
  SpanBuffer bare;
  CHECK(call_of([&] { rt.set_feedback(bare); }).find("neither its samples") != std::string::npos);
  rt.request(TileKey(0, 2, 1, 1));
  bare.has_samples = true;
  CHECK(call_of([&] { rt.set_feedback(bare); }).find("already has request()s") != std::string::npos);
  rt.end_frame(gpu);
  // Time running backwards.
  rt.begin_frame(10);
  rt.end_frame(gpu);
  CHECK(call_of([&] { rt.begin_frame(5); }).find("before the previous frame") != std::string::npos);
}

TEST_CASE("runtime: a clipmap frame without a camera is refused") {
  const ReplayConfig cfg = runtime_cfg("clipmap");
  auto scene = make_scene_from_config(cfg);
  StreamingRuntime rt(runtime_parts(cfg, scene->texture(), 1.0 / 60, nullptr, nullptr));
  test::FakeGpu gpu(1, 0, 0);
  rt.begin_frame(0);
  CHECK_THROWS_WITH_AS(rt.end_frame(gpu), doctest::Contains("StreamingRuntime::end_frame: a clipmap follows the camera"), RuntimeCallError);
  // The refused frame is still open: with a camera it ends.
  rt.set_camera(pose_from_angles({100.0, 100.0, 2.0}, 0.0, -10.0));
  CHECK(rt.end_frame(gpu).windows.size() == static_cast<std::size_t>(rt.system().num_levels()));
}
