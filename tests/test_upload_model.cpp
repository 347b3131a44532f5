// The simulated clock's upload copy (device_model.h: upload.per_tile_us + bytes / upload.link_MBps)
// and its calibration's fit (stream/exec/upload_fit.h, `vtsim gl calibrate-upload`): the fit
// recovers known parameters exactly, the profile loads as a config, a tile's upload stage takes
// exactly per_tile_us, and the link's budget is a frame of copy time, to the tick.
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "core/error.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "sim/trace/trace_gen.h"
#include "stream/exec/pipeline.h"
#include "stream/exec/sim_executor.h"
#include "stream/exec/upload_fit.h"
#include "trace_test_util.h"

using namespace vtsim;

namespace {

// Frames of `tiles` pages of `bytes` each, timed exactly by the model (a + b·bytes per page).
std::vector<UploadSample> model_samples(double a_us, double mbps, double frame_us = 0.0) {
  std::vector<UploadSample> s;
  for (const std::uint64_t bytes : {18496ull, 73984ull, 295936ull})
    for (const int tiles : {1, 4, 16, 64}) s.push_back({bytes, tiles, frame_us + tiles * (a_us + static_cast<double>(bytes) / mbps)});
  return s;
}

Need upload_need(std::int64_t x) { return Need{TileKey(0, 0, x, 0), make_priority(0, 0, 0), false}; }

// A still camera over the plane (level 0 on screen), 0.5 s at 60 Hz.
Trace still_trace() {
  TraceGenParams p = default_gen_params("static");
  p.duration_s = 0.5;
  p.image_width = 320;
  p.image_height = 180;
  return generate_trace(p);
}

std::vector<std::string> upload_sets(const std::string& per_tile_us) {
  return {"disk.preset=unconstrained", "upload.tiles_per_frame=-1", "upload.link_MBps=0", "throttle.policy=none",
          "io.max_in_flight=1000000",  "run.fps=60",                 "upload.per_tile_us=" + per_tile_us};
}

ReplayResult upload_replay(const std::vector<std::string>& sets) {
  const ReplayConfig cfg = load_replay_config("", sets);
  auto scene = make_scene_from_config(cfg);
  return run_replay(cfg, still_trace(), *scene);
}

}  // namespace

TEST_CASE("upload fit: recovers the per-page cost and the bandwidth of synthetic timings exactly") {
  const UploadFit f = fit_upload_model(model_samples(12.5, 800.0));
  CHECK(f.per_tile_us == doctest::Approx(12.5).epsilon(1e-9));
  CHECK(f.MBps == doctest::Approx(800.0).epsilon(1e-9));
  CHECK(f.per_frame_us == doctest::Approx(0.0).epsilon(1e-9));
  CHECK(f.max_abs_rel < 1e-9);
  CHECK(f.notes.empty());
  REQUIRE(f.model_us.size() == 12);
  CHECK(f.model_us[5] == doctest::Approx(4 * (12.5 + 73984.0 / 800.0)).epsilon(1e-9));
  // With a frame's fixed cost (the timer query, the fence): recovered beside the per-page terms.
  const UploadFit g = fit_upload_model(model_samples(3.0, 2000.0, 45.0));
  CHECK(g.per_tile_us == doctest::Approx(3.0).epsilon(1e-9));
  CHECK(g.MBps == doctest::Approx(2000.0).epsilon(1e-9));
  CHECK(g.per_frame_us == doctest::Approx(45.0).epsilon(1e-9));
  CHECK(g.max_abs_rel < 1e-9);
}

TEST_CASE("upload fit: a negative term is left out and said, bad samples are refused") {
  // Per-page times that fall with the bytes (one batch size: no frame term): the mean per page.
  const UploadFit f = fit_upload_model({{1000, 1, 30.0}, {4000, 1, 20.0}});
  CHECK(f.MBps == 0.0);
  CHECK(f.per_tile_us == doctest::Approx(25.0));
  CHECK(f.per_frame_us == 0.0);
  CHECK(f.notes.size() == 2);  // no per-byte cost, no frame cost (it cannot be told from the per-page one)
  // 1 us a page at 1000 B, 6 at 4000 B: a < 0 with b, so b alone through the origin: Σxy / Σx².
  const UploadFit g = fit_upload_model({{1000, 1, 1.0}, {4000, 1, 6.0}});
  CHECK(g.per_tile_us == 0.0);
  CHECK(g.MBps == doctest::Approx((1000.0 * 1000 + 4000.0 * 4000) / (1000.0 * 1 + 4000.0 * 6)));
  // Weights: a sample weighing 3x pulls the one-term fit to it (3·20 + 30) / 4.
  const UploadFit h = fit_upload_model({{1000, 1, 30.0, 1.0}, {4000, 1, 20.0, 3.0}});
  CHECK(h.per_tile_us == doctest::Approx(22.5));
  CHECK_THROWS_AS(fit_upload_model({}), std::invalid_argument);
  CHECK_THROWS_AS(fit_upload_model({{1000, 0, 1.0}}), std::invalid_argument);
  CHECK_THROWS_AS(fit_upload_model({{1000, 1, -1.0}}), std::invalid_argument);
  CHECK_THROWS_AS(fit_upload_model({{1000, 1, 1.0, 0.0}}), std::invalid_argument);
}

TEST_CASE("upload fit: the profile is an [upload] table that loads as a config, beside calibrate's keys") {
  const std::vector<UploadSample> s = model_samples(12.5, 800.0);
  const std::string toml = upload_profile_toml(fit_upload_model(s), s, "test");
  ScratchDir dir;
  write_file(dir.file("upload.toml"), toml);
  write_file(dir.file("io.toml"), "[disk]\nlatency_us = 100.0\n[decode]\nper_tile_us = 50.0\n");
  const ReplayConfig c = load_replay_config(std::vector<std::string>{dir.file("io.toml"), dir.file("upload.toml")}, {}, "");
  CHECK(c.upload.per_tile_us == doctest::Approx(12.5).epsilon(1e-6));
  CHECK(c.upload.link_MBps == doctest::Approx(800.0).epsilon(1e-6));
  CHECK(c.disk.latency_us == 100.0);
  CHECK(c.decode.per_tile_us == 50.0);
  CHECK(c.upload.tiles_per_frame == ReplayConfig{}.upload.tiles_per_frame);
}

TEST_CASE("upload model: a copy takes per_tile_us + bytes / link_MBps to the tick, per_tile_us = 0 is the link alone") {
  UploadModel m;
  m.link_MBps = 1000.0;  // 1 byte a ns
  CHECK(upload_ticks(m, 65536) == 65536);
  CHECK(upload_ticks(m, 65536) == transfer_ticks(65536, m.link_MBps * 1e6));
  m.per_tile_us = 7.25;
  CHECK(upload_ticks(m, 65536) == 7250 + 65536);
  m.link_MBps = 0.0;
  CHECK(upload_ticks(m, 65536) == 7250);
  CHECK(upload_ticks(m, 0) == 7250);
  CHECK_THROWS_AS(load_replay_config("", {"upload.per_tile_us=-1"}), InputError);
}

TEST_CASE("upload model: boundary — the link's frame of copy time fits a copy ending exactly at it, not one tick over") {
  SimExecutor ex(DiskModel{0.0, 0.0, 0}, DecodeModel{}, 64);
  Pipeline p(PipelineConfig{}, ex, [](TileKey) { return TileSizes{65536, 65536}; });
  const auto take = [&](int f, Ticks link_ticks, const std::vector<Need>& needs) {
    p.begin_frame(f, f * 1'000'000);
    p.set_needs(needs);
    p.dispatch();
    std::vector<UploadItem> up;
    UploadBudget b;
    b.link_ticks = link_ticks;
    b.per_tile_ticks = 5000;
    b.link_Bps = 1e9;  // 65536 ticks a tile
    p.take_uploads(b, up);
    return up.size();
  };
  // The third copy would end one tick after the frame's budget: two of four.
  CHECK(take(0, 3 * 70536 - 1, {upload_need(1), upload_need(2), upload_need(3), upload_need(4)}) == 2);
  CHECK(take(1, 2 * 70536, {upload_need(3), upload_need(4)}) == 2);  // the remaining two end exactly at it
}

TEST_CASE("upload model: in the replay each tile's upload stage is exactly per_tile_us, and a frame holds period / per_tile_us copies") {
  // 60 Hz: a frame of 16,666,667 ticks holds 4 copies of 4,166,666 ns (16,666,664), not 5.
  const ReplayResult r = upload_replay(upload_sets("4166.666"));
  const nlohmann::json& up = r.summary["latency_ms"]["stages_ms"]["upload"];
  REQUIRE(up["count"].get<std::size_t>() > 0);
  CHECK(up["p50"].get<double>() == doctest::Approx(4.166666).epsilon(1e-12));
  CHECK(up["max"].get<double>() == doctest::Approx(4.166666).epsilon(1e-12));
  CHECK(r.summary["bandwidth"]["upload_tiles_per_frame"]["max"].get<double>() == 4.0);
  // A copy one nanosecond longer: 4 × 4,166,667 = 16,666,668 ticks is over the frame: 3 a frame.
  const ReplayResult r3 = upload_replay(upload_sets("4166.667"));
  CHECK(r3.summary["bandwidth"]["upload_tiles_per_frame"]["max"].get<double>() == 3.0);
  CHECK(r3.summary["latency_ms"]["stages_ms"]["upload"]["max"].get<double>() == doctest::Approx(4.166667).epsilon(1e-12));
  // per_tile_us = 0 and the link alone: the stage is bytes / link as before (64 KiB at 1000 MB/s).
  std::vector<std::string> sets = upload_sets("0");
  sets.push_back("upload.link_MBps=1000");
  const ReplayResult r0 = upload_replay(sets);
  CHECK(r0.summary["latency_ms"]["stages_ms"]["upload"]["max"].get<double>() == doctest::Approx(0.065536).epsilon(1e-12));
}

TEST_CASE("upload model: a copy longer than a frame is refused, naming upload.per_tile_us") {
  const std::string e = input_error([] { upload_replay(upload_sets("20000")); });
  CHECK(e.find("upload.per_tile_us") != std::string::npos);
}
