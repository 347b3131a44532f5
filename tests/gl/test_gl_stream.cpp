// The GL client streaming through the runtime (docs/gpu.md, "Streaming through the runtime"): a
// tiny VT store streamed on a still camera in the real clock, the feedback at full resolution so
// the main pass wants exactly the pages the feedback requested. No GL error; every tile the
// runtime uploaded reached the GPU's sink; the GPU's page table maps only resident pages (each
// entry a resident page's slot and level); and the fully streamed view ends with no blurry pixel.
#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <unistd.h>

#include "core/error.h"
#include "gl/gl_replay.h"
#include "gl_test_util.h"
#include "sim/run/feedback_replay.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay_config.h"
#include "sim/trace/feedback_trace.h"
#include "sim/trace/trace_gen.h"
#include "stream/store/store_generator.h"
#include "stream/store/tile_store.h"

namespace {

using namespace vtsim;

std::string slurp_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// 512² texels (16 m at 32 texels/m), pages of 64 + 4-texel borders, one RGBA8 layer: 94 pages.
std::string gl_stream_store() {
  const std::string p = (std::filesystem::temp_directory_path() / ("vtsim-gl-stream-" + std::to_string(::getpid()) + ".vts")).string();
  GenOptions g;
  g.width = g.height = 512;
  g.tile = 64;
  g.border = 4;
  g.seed = 3;
  g.feature_texels = 128;
  g.threads = 1;
  g.layers = parse_gen_layers("albedo:raw", "layers");
  generate_store(g, p);
  return p;
}

}  // namespace

TEST_CASE("gl: streaming a still view through the runtime uploads the runtime's pages and ends sharp") {
  const std::string path = gl_stream_store();
  const TileStore store = TileStore::open(path);
  const ReplayConfig cfg = load_replay_config("", {"texture.texels_per_m=32", "view.divisor=1"}, "vt");
  TraceGenParams tg = default_gen_params("static");
  tg.start_m = {8.0, 8.0};
  tg.duration_s = 1.0;  // 60 frames: the view is streamed within ~10 of them, the rest is margin for a loaded machine
  tg.image_width = 256;
  tg.image_height = 144;
  const Trace trace = generate_trace(tg);
  gl_test::Shared& gs = gl_test::shared();
  gs.warnings.clear();
  const int errors_before = gs.ctx.errors();
  gl::GlReplayOptions o;
  o.latency = 2;
  o.record_feedback = path + ".vtfb";  // the GPU's feedback as a feedback trace (docs/feedback.md)
  const gl::GlReplayRun run = gl::run_gl_replay(gs.ctx, cfg, trace, store, o);
  std::filesystem::remove(path);
  const nlohmann::json& s = run.result.summary;
  INFO(s["popin"].dump());
  CHECK(gs.warnings.empty());
  CHECK(gs.ctx.errors() == errors_before);
  REQUIRE(run.sink_uploads > 10);
  CHECK(run.sink_uploads == s["bandwidth"]["uploads"].get<std::uint64_t>());
  CHECK(run.gpu_copies == run.sink_uploads);  // one layer: every upload is a page copied
  CHECK(run.page_table_consistent);
  CHECK(run.page_table.size() == run.pool_pages.size());
  const std::vector<FrameRow>& rows = run.result.metrics.frames();
  REQUIRE(rows.size() >= 30);
  CHECK(rows.front().blurry > 0);        // the first frames had nothing resident
  CHECK(rows.back().samples > 10000u);   // the plane fills most of the view
  CHECK(rows.back().blurry == 0u);       // streamed: every pixel samples the level it wants
  CHECK(rows.back().needs == 0u);

  // The recorded GPU feedback: a frame per frame run, fresh where a readback arrived, and its last
  // fresh frame's tiles are pages the GPU's page table holds (the view it asked for, streamed).
  FeedbackReader rd(o.record_feedback);
  CHECK(rd.header().texture.width == 512);  // the store's (gl_stream_store), bound by gl replay
  CHECK(rd.header().tile_size == 64u);
  FeedbackFrame f, last_fresh;
  std::uint64_t frames = 0, fresh = 0;
  while (rd.next(f)) {
    ++frames;
    if (f.fresh) {
      ++fresh;
      last_fresh = f;
    }
  }
  CHECK(frames == rows.size());
  // Every readback, and frame 0 (no readback yet at latency 2: its feedback is empty).
  CHECK(fresh == s["gl"]["feedback_frames_read"].get<std::uint64_t>() + 1);
  REQUIRE_FALSE(last_fresh.tiles.empty());
  std::uint64_t samples = 0;
  for (const FeedbackTile& t : last_fresh.tiles) {
    CAPTURE(t.level);
    CAPTURE(t.x);
    CAPTURE(t.y);
    CHECK(run.page_table.count(TileKey(0, t.level, static_cast<std::int64_t>(t.x), static_cast<std::int64_t>(t.y))) == 1);
    samples += t.samples;
  }
  CHECK(samples <= static_cast<std::uint64_t>(256 * 144));
  // The simulator replays the GPU's feedback (vtsim replay --feedback): it streams the same view
  // to sharp in the simulated clock.
  ReplayConfig bound = cfg;
  (void)bind_store_texture(bound, store);
  const ReplayResult sim = run_feedback_replay(bound, o.record_feedback);
  std::filesystem::remove(o.record_feedback);
  REQUIRE_FALSE(sim.metrics.frames().empty());
  CHECK(sim.metrics.frames().back().blurry == 0u);
  CHECK(sim.summary["bandwidth"]["uploads"].get<std::uint64_t>() > 10);
}

TEST_CASE("gl: gl replay refuses a config the store does not match, before the first frame") {
  const std::string path = gl_stream_store();
  const TileStore store = TileStore::open(path);
  TraceGenParams tg = default_gen_params("static");
  tg.start_m = {8.0, 8.0};
  tg.duration_s = 0.1;
  tg.image_width = 64;
  tg.image_height = 36;
  const Trace trace = generate_trace(tg);
  gl_test::Shared& gs = gl_test::shared();
  const auto refused = [&](const std::vector<std::string>& sets) -> std::string {
    try {
      (void)gl::run_gl_replay(gs.ctx, load_replay_config("", sets, "vt"), trace, store);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  CHECK(refused({"texture.texels_per_m=32", "texture.tile_size=32"}).find("texture.tile_size") != std::string::npos);
  CHECK(refused({"texture.texels_per_m=32", "texture.width=1024", "texture.height=1024"}).find("texture.width") != std::string::npos);
  CHECK(refused({"texture.texels_per_m=32", "vt.pool_pages=10000000"}).find("vt.pool_pages") != std::string::npos);
  std::filesystem::remove(path);
}

TEST_CASE("gl: --video writes every frame through ffmpeg, and without ffmpeg refuses before the first frame") {
  const std::string path = gl_stream_store();
  const TileStore store = TileStore::open(path);
  const ReplayConfig cfg = load_replay_config("", {"texture.texels_per_m=32", "view.divisor=1"}, "vt");
  TraceGenParams tg = default_gen_params("static");
  tg.start_m = {8.0, 8.0};
  tg.duration_s = 0.25;  // 16 frames (0 to 0.25 s at 60 Hz)
  tg.image_width = 128;
  tg.image_height = 72;
  const Trace trace = generate_trace(tg);
  gl_test::Shared& gs = gl_test::shared();
  gl::GlReplayOptions o;
  o.pace = false;
  o.video = path + ".mp4";
  {  // ffmpeg not on PATH: an InputError naming --video, and the existing file is left as it was.
    std::ofstream(o.video) << "old";
    const std::string saved = std::getenv("PATH") ? std::getenv("PATH") : "";
    ::setenv("PATH", "/nonexistent-vtsim-path", 1);
    CHECK_THROWS_WITH_AS(gl::run_gl_replay(gs.ctx, cfg, trace, store, o), doctest::Contains("--video"), InputError);
    ::setenv("PATH", saved.c_str(), 1);
    CHECK(slurp_file(o.video) == "old");
  }
  if (std::system("ffprobe -version > /dev/null 2>&1") != 0) {
    MESSAGE("ffmpeg is not installed: the video itself is not checked (scripts/test.sh installs it)");
  } else {
    const gl::GlReplayRun run = gl::run_gl_replay(gs.ctx, cfg, trace, store, o);
    const std::size_t frames = run.result.metrics.frames().size();
    CHECK(frames == 16u);
    CHECK(run.video_frames == frames);
    const std::string probe = path + ".probe";
    REQUIRE(std::system(("ffprobe -v error -count_frames -select_streams v:0 -show_entries stream=nb_read_frames,width,height "
                         "-of csv=p=0 '" + o.video + "' > '" + probe + "'").c_str()) == 0);
    CHECK(slurp_file(probe) == "128,72," + std::to_string(frames) + "\n");  // every frame, at the trace's size
    std::filesystem::remove(probe);
  }
  std::filesystem::remove(o.video);
  std::filesystem::remove(path);
}
