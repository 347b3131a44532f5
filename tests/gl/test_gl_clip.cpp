// The GL client's clip stack (docs/gpu.md, "The clipmap: a clip stack on the GPU"): a small
// clipmap store streamed on a still camera through the runtime in the real clock. No GL error;
// every tile the runtime uploaded reached the GPU's sink and was copied; the shader's windows are
// the runtime's clip_windows and each window tile's GPU slot is valid exactly when the clipmap
// holds it; the streamed view ends sharp. Then the rule itself against the simulator: with a
// clipsize too small for the view, the last frame's blurry pixels (the windows full, so the count
// depends on the level-selection rule only) equal the simulated replay's.
#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>

#include "core/error.h"
#include "gl/gl_replay.h"
#include "gl_test_util.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "sim/run/resources.h"
#include "sim/trace/trace_gen.h"
#include "sim/view/scene.h"
#include "stream/store/store_generator.h"
#include "stream/store/tile_store.h"

namespace {

using namespace vtsim;

// 1024² texels (64 m at 16 texels/m), 64-texel tiles without borders (a clipmap's), one RGBA8
// layer, every level down to 1×1: 347 tiles.
std::string gl_clip_store() {
  const std::string p = (std::filesystem::temp_directory_path() / ("vtsim-gl-clip-" + std::to_string(::getpid()) + ".vts")).string();
  GenOptions g;
  g.width = g.height = 1024;
  g.tile = 64;
  g.border = 0;
  g.seed = 5;
  g.feature_texels = 128;
  g.threads = 1;
  g.layers = parse_gen_layers("albedo:raw", "layers");
  generate_store(g, p);
  return p;
}

Trace gl_clip_still(double seconds) {
  TraceGenParams tg = default_gen_params("static");
  tg.start_m = {32.0, 32.0};
  tg.duration_s = seconds;
  tg.image_width = 256;
  tg.image_height = 144;
  return generate_trace(tg);
}

std::vector<std::string> gl_clip_sets(int clipsize) {
  return {"run.system=clipmap", "texture.texels_per_m=16", "view.divisor=1", "view.lod_model=gpu", "view.popin_divisor=1",
          "clipmap.clipsize=" + std::to_string(clipsize)};
}

}  // namespace

TEST_CASE("gl: a clipmap streamed through the runtime fills the GPU's clip stack with the runtime's windows and ends sharp") {
  const std::string path = gl_clip_store();
  const TileStore store = TileStore::open(path);
  // Clipsize 256: levels 0 (1024²) and 1 (512²) are the stack (4×4-tile windows), 2.. the pyramid.
  const ReplayConfig cfg = load_replay_config("", gl_clip_sets(256), "vt");
  const Trace trace = gl_clip_still(1.0);  // 60 frames: streamed within ~10, the rest is margin for a loaded machine
  gl_test::Shared& gs = gl_test::shared();
  gs.warnings.clear();
  const int errors_before = gs.ctx.errors();
  gl::GlReplayOptions o;
  o.latency = 2;
  const gl::GlReplayRun run = gl::run_gl_replay(gs.ctx, cfg, trace, store, o);
  std::filesystem::remove(path);
  const nlohmann::json& s = run.result.summary;
  INFO(s["popin"].dump());
  CHECK(gs.warnings.empty());
  CHECK(gs.ctx.errors() == errors_before);
  REQUIRE(run.sink_uploads > 10);
  CHECK(run.sink_uploads == s["bandwidth"]["uploads"].get<std::uint64_t>());
  CHECK(run.gpu_copies == run.sink_uploads);  // one layer: every upload is a tile copied
  CHECK(s["clipmap"]["stack_levels"].get<int>() == 2);
  CHECK(s["gl"]["clip_stack_consistent"].get<bool>());
  CHECK(run.clip_consistent);
  REQUIRE(run.gpu_windows.size() == 11u);  // 1024² down to 1×1
  CHECK(run.gpu_windows == run.runtime_windows);
  CHECK(run.gpu_windows[0].w == 4);  // a stack level: a 4×4-tile window inside 16×16 tiles
  CHECK(run.gpu_windows[0].h == 4);
  CHECK(run.gpu_windows[0].x0 > 0);  // centred under the camera, not at the texture's corner
  CHECK(run.gpu_windows[2] == ClipWindow{0, 0, 4, 4});  // the pyramid's first level: whole
  const std::vector<FrameRow>& rows = run.result.metrics.frames();
  REQUIRE(rows.size() >= 30);
  CHECK(rows.front().blurry > 0);        // the first frames had nothing resident
  CHECK(rows.back().samples > 10000u);   // the plane fills most of the view
  CHECK(rows.back().blurry == 0u);       // streamed: every pixel samples the level it wants
  CHECK(rows.back().needs == 0u);
}

TEST_CASE("gl: the clip stack's level selection is the simulator's: a view wider than the windows ends as blurry on both") {
  const std::string path = gl_clip_store();
  const TileStore store = TileStore::open(path);
  // Clipsize 128 (2×2-tile windows on levels 0..2): the view wants level 0 beyond level 0's window,
  // so ~6 % of the view stays blurry once every window is full.
  ReplayConfig cfg = load_replay_config("", gl_clip_sets(128), "vt");
  const Trace trace = gl_clip_still(1.0);  // paced: 60 frames of real time for ~23 tiles, whatever the load
  gl_test::Shared& gs = gl_test::shared();
  gl::GlReplayOptions o;
  o.latency = 0;
  const gl::GlReplayRun run = gl::run_gl_replay(gs.ctx, cfg, trace, store, o);
  (void)bind_store_texture(cfg, store);
  const std::unique_ptr<IScene> scene = make_scene_from_config(cfg);
  const ReplayResult sim = run_replay(cfg, trace, *scene);
  std::filesystem::remove(path);
  CHECK(run.clip_consistent);
  const FrameRow& g = run.result.metrics.frames().back();
  const FrameRow& m = sim.metrics.frames().back();
  REQUIRE(g.needs == 0u);  // every window full: the count depends on the rule only
  REQUIRE(m.needs == 0u);
  CAPTURE(g.samples);
  CAPTURE(m.samples);
  CAPTURE(g.blurry);
  CAPTURE(m.blurry);
  CHECK(m.blurry > 500u);
  // The same pixels: the GPU rasterises what the simulator's GPU model ray-casts (equal on
  // llvmpipe; a pixel or two may differ at the horizon elsewhere), and the same rule picks each
  // pixel's level.
  CHECK(std::abs(static_cast<long>(g.samples) - static_cast<long>(m.samples)) <= 8);
  CHECK(std::abs(static_cast<long>(g.blurry) - static_cast<long>(m.blurry)) <= 8);
  CHECK(g.deficit_sum == doctest::Approx(m.deficit_sum).epsilon(0.01));
}

TEST_CASE("gl: gl replay refuses a clipmap it cannot draw, before the first frame") {
  const std::string path = gl_clip_store();
  const TileStore store = TileStore::open(path);
  const Trace trace = gl_clip_still(0.1);
  gl_test::Shared& gs = gl_test::shared();
  const auto refused = [&](const std::vector<std::string>& sets) -> std::string {
    try {
      (void)gl::run_gl_replay(gs.ctx, load_replay_config("", sets, "vt"), trace, store);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  std::vector<std::string> sets = gl_clip_sets(256);
  sets.push_back("texture.border=4");  // the store has none, and a clipmap takes none
  CHECK(refused(sets).find("texture.border") != std::string::npos);
  sets = gl_clip_sets(96);  // not a multiple of the 64-texel tiles
  CHECK(refused(sets).find("clipmap.clipsize") != std::string::npos);
  sets = gl_clip_sets(256);
  sets.push_back("texture.tile_size=32");
  CHECK(refused(sets).find("texture.tile_size") != std::string::npos);
  std::filesystem::remove(path);
}
