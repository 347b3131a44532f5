// Feedback traces (sim/trace/feedback_trace.h, sim/run/feedback_replay.h, docs/feedback.md): the
// format round-trips, the reader refuses bad files with file:frame:field, and a replay from a
// recorded feedback trace equals the camera replay it was recorded from.
#include <doctest/doctest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/error.h"
#include "sim/run/feedback_replay.h"
#include "sim/run/replay.h"
#include "sim/sweep/lockstep.h"
#include "sim/sweep/sweep_spec.h"
#include "sim/trace/feedback_trace.h"
#include "sim/trace/trace_io.h"
#include "test_util.h"

using namespace vtsim;

namespace {

std::string fb_tmp(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("vtsim_fb_" + std::to_string(::getpid()) + "_" + name)).string();
}

FeedbackHeader fb_header() {
  FeedbackHeader h;
  h.texture = {4096, 2048};
  h.tile_size = 128;
  h.levels = 13;
  h.feedback_width = 240;
  h.feedback_height = 135;
  h.image_width = 1920;
  h.image_height = 1080;
  h.frame_rate = 30.0;
  return h;
}

std::string fb_slurp(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The error message reading `bytes` gives (empty: read whole without error).
std::string fb_read_error(const std::string& bytes) {
  try {
    FeedbackReader r(std::make_unique<std::istringstream>(bytes), "t.vtfb");
    FeedbackFrame f;
    while (r.next(f)) {
    }
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

// Writes frames through the writer and returns the file's bytes.
std::string fb_write(const std::vector<FeedbackFrame>& frames, std::uint32_t per_block = 64) {
  const std::string p = fb_tmp("w.vtfb");
  {
    FeedbackWriter w(p, fb_header(), per_block);
    for (const FeedbackFrame& f : frames) w.add(f);
    w.finish();
  }
  std::string b = fb_slurp(p);
  std::filesystem::remove(p);
  return b;
}

std::vector<FeedbackFrame> fb_frames() {
  std::vector<FeedbackFrame> v;
  for (int i = 0; i < 5; ++i) {
    FeedbackFrame f;
    f.t_s = i / 30.0;
    f.has_pose = i % 2 == 0;
    if (f.has_pose) {
      f.pose.t_s = f.t_s;
      f.pose.pos_m = {1.0 * i, 2.0, 3.5};
      f.pose.vfov_deg = 70.0;
    }
    f.fresh = i != 3;
    f.measured = i != 3;
    if (f.fresh) f.tiles = {{0, 0, 3, 4, 10}, {0, 0, 31, 0, 1}, {2, 0, 1, 1, 7}, {12, 0, 0, 0, 99}};
    v.push_back(f);
  }
  return v;
}

}  // namespace

TEST_CASE("feedback trace: frames round-trip through the writer and the reader") {
  const std::vector<FeedbackFrame> in = fb_frames();
  for (const std::uint32_t per_block : {1u, 2u, 64u}) {
    const std::string bytes = fb_write(in, per_block);
    FeedbackReader r(std::make_unique<std::istringstream>(bytes), "t.vtfb");
    CHECK(r.header().texture.width == 4096);
    CHECK(r.header().levels == 13);
    CHECK(r.header().frame_rate == 30.0);
    FeedbackFrame f;
    for (const FeedbackFrame& want : in) {
      REQUIRE(r.next(f));
      CHECK(f.t_s == want.t_s);
      CHECK(f.has_pose == want.has_pose);
      CHECK(f.fresh == want.fresh);
      CHECK(f.measured == want.measured);
      CHECK(f.pose.pos_m == want.pose.pos_m);
      CHECK(f.tiles == want.tiles);
    }
    CHECK_FALSE(r.next(f));
  }
}

TEST_CASE("feedback trace: bad files are refused with file:frame and the field") {
  const std::vector<FeedbackFrame> good = fb_frames();
  CHECK(fb_read_error(fb_write(good)).empty());
  const auto with = [&](int frame, auto edit) {
    std::vector<FeedbackFrame> v = good;
    edit(v[static_cast<std::size_t>(frame)]);
    return fb_read_error(fb_write(v));
  };
  std::string e = with(1, [](FeedbackFrame& f) { f.tiles[1].x = 32; });  // 4096 / 128 = 32 tiles at level 0
  CHECK(e.find("t.vtfb:frame 1") != std::string::npos);
  CHECK(e.find("tile.x") != std::string::npos);
  e = with(2, [](FeedbackFrame& f) { f.tiles[3].level = 13; });
  CHECK(e.find("t.vtfb:frame 2") != std::string::npos);
  CHECK(e.find("tile.level") != std::string::npos);
  e = with(2, [](FeedbackFrame& f) { f.tiles[3].samples = 0; });
  CHECK(e.find("tile.samples") != std::string::npos);
  e = with(0, [](FeedbackFrame& f) { std::swap(f.tiles[0], f.tiles[1]); });
  CHECK(e.find("field 'tile'") != std::string::npos);
  // Frames out of order: the writer refuses them, so the bytes are patched: frame 1's time (the
  // 8 bytes after its flags) cannot be found in compressed bytes; write blocks of one frame and
  // swap two whole blocks instead.
  {
    const std::string b = fb_write(good, 1);
    CHECK(fb_read_error(b).empty());
    std::vector<std::string> blocks;
    std::size_t at = kFeedbackHeaderBytes;
    while (b.compare(at, 4, "BLK1") == 0) {
      const std::uint32_t comp = static_cast<unsigned char>(b[at + 20]) | static_cast<unsigned char>(b[at + 21]) << 8;
      blocks.push_back(b.substr(at, 32 + comp));
      at += 32 + comp;
    }
    REQUIRE(blocks.size() == good.size());
    const std::string swapped = b.substr(0, kFeedbackHeaderBytes) + blocks[1] + blocks[0] + b.substr(kFeedbackHeaderBytes + blocks[0].size() + blocks[1].size());
    e = fb_read_error(swapped);
    CHECK(e.find("t.vtfb:frame 0") != std::string::npos);
    CHECK(e.find("out of order") != std::string::npos);
  }
  // Truncated anywhere (the header, a block, at a block boundary before the end record): refused.
  const std::string b = fb_write(good, 2);
  for (std::size_t n = 0; n < b.size(); n += 7) {
    CAPTURE(n);
    e = fb_read_error(b.substr(0, n));
    CHECK_FALSE(e.empty());
  }
  CHECK(fb_read_error(b.substr(0, b.size() - 24)).find("truncated") != std::string::npos);
  // One flipped byte anywhere: refused (checksums, zstd), never a crash.
  for (std::size_t i = 0; i < b.size(); i += 3) {
    std::string c = b;
    c[i] = static_cast<char>(c[i] ^ 0x5a);
    CAPTURE(i);
    CHECK_FALSE(fb_read_error(c).empty());
  }
  e = fb_read_error("NOTATRACE");
  CHECK(e.find("t.vtfb:header") != std::string::npos);
}

TEST_CASE("feedback replay: a replay from a recorded feedback trace equals the camera replay") {
  Trace walk = load_trace(test::kData + "/town_walk.csv");
  while (!walk.poses.empty() && walk.poses.back().t_s > 3.0) walk.poses.pop_back();
  const ReplayConfig cfg = load_replay_config(
      "", {"scene.kind=town", "view.render_threads=0", "run.system=vt", "vt.pool_pages=300", "upload.tiles_per_frame=6"});
  const auto scene = make_scene_from_config(cfg);
  const std::string path = fb_tmp("town.vtfb");
  FeedbackRecorder rec(path, cfg);
  ReplayEnv env;
  env.on_view = [&rec](const FramePlan& p, const FrameView& v) { rec(p, v); };
  ReplayResult cam = run_replay(cfg, walk, *scene, env);
  rec.finish();
  ReplayResult fb = run_feedback_replay(cfg, path, {});
  std::filesystem::remove(path);
  // Not metrics: the run's cost and the trace's identity (its file and name).
  for (ReplayResult* r : {&cam, &fb}) {
    r->summary.erase("run");
    r->summary["trace"].erase("name");
    r->summary["trace"].erase("path");
    r->summary["trace"].erase("feedback");
  }
  CHECK(cam.metrics.frames().size() == fb.metrics.frames().size());
  for (auto it = cam.summary.begin(); it != cam.summary.end(); ++it) {
    CAPTURE(it.key());
    REQUIRE(fb.summary.contains(it.key()));
    CHECK(it.value().dump() == fb.summary[it.key()].dump());
  }
  CHECK(cam.summary.size() == fb.summary.size());
  for (std::size_t i = 0; i < cam.metrics.frames().size(); ++i) {
    CAPTURE(i);
    CHECK(cam.metrics.frames()[i] == fb.metrics.frames()[i]);
  }
  CHECK(cam.summary["bandwidth"]["uploads"].get<std::uint64_t>() > 0);
}

TEST_CASE("feedback replay: runs that need per-sample LODs or another texture are refused") {
  const std::string path = fb_tmp("refuse.vtfb");
  {
    FeedbackWriter w(path, fb_header());
    for (const FeedbackFrame& f : fb_frames()) w.add(f);
    w.finish();
  }
  const auto refusal = [&](const std::vector<std::string>& sets) {
    try {
      (void)run_feedback_replay(load_replay_config("", sets), path, {});
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::vector<std::string> ok = {"run.system=vt", "texture.width=4096", "texture.height=2048"};
  CHECK(refusal(ok).empty());
  auto with = [&](std::string s) {
    auto v = ok;
    v.push_back(std::move(s));
    return refusal(v);
  };
  CHECK(with("throttle.policy=unreal_bias").find("may bias the feedback") != std::string::npos);
  CHECK(with("view.popin_divisor=2").find("view.popin_divisor") != std::string::npos);
  CHECK(with("texture.tile_size=256").find("field 'tile_size'") != std::string::npos);
  CHECK(with("run.system=clipmap").find("vt") != std::string::npos);
  std::filesystem::remove(path);
}

TEST_CASE("feedback sweep: a feedback trace as a sweep's trace gives each config its camera replay's metrics") {
  Trace walk = load_trace(test::kData + "/town_walk.csv");
  while (!walk.poses.empty() && walk.poses.back().t_s > 1.5) walk.poses.pop_back();
  const ReplayConfig a = load_replay_config("", {"scene.kind=town", "view.render_threads=0", "run.system=vt", "vt.pool_pages=200"});
  const ReplayConfig b = load_replay_config("", {"scene.kind=town", "view.render_threads=0", "run.system=vt", "vt.pool_pages=600",
                                                 "upload.tiles_per_frame=3"});
  const auto scene = make_scene_from_config(a);
  const std::string path = fb_tmp("sweep.vtfb");
  {
    FeedbackRecorder rec(path, a);
    ReplayEnv env;
    env.on_view = [&rec](const FramePlan& p, const FrameView& v) { rec(p, v); };
    (void)run_replay(a, walk, *scene, env);
    rec.finish();
  }
  SweepTraceSource src;
  src.text = path;
  const Trace fb = load_sweep_trace(src);
  CHECK(fb.source_path == path);
  CHECK(fb.poses.size() == plan_frames(a, walk).trace.poses.size());
  const std::vector<LockstepResult> cam = run_lockstep({&a, &b}, walk, *scene, 1);
  const std::vector<LockstepResult> fed = run_lockstep({&a, &b}, fb, *scene, 1);
  std::filesystem::remove(path);
  REQUIRE(cam.size() == 2);
  REQUIRE(fed.size() == 2);
  for (std::size_t i = 0; i < 2; ++i) {
    CAPTURE(i);
    REQUIRE(cam[i].ok);
    REQUIRE(fed[i].ok);
    nlohmann::json x = cam[i].summary, y = fed[i].summary;
    x.erase("trace");
    y.erase("trace");
    CHECK(x.dump() == y.dump());
  }
  CHECK(cam[0].summary["bandwidth"].dump() != cam[1].summary["bandwidth"].dump());  // the configs differ
}
