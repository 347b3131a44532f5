// The streaming runtime an engine calls (stream/runtime/streaming_runtime.h) in the real clock:
// an engine's loop over a store, with the runtime's IO and decode pools and a fake GPU whose
// physical page pool is host memory, ends with the residency and uploads of the real-clock replay
// on the same view, every mapped page byte-exact in its slot; a store that does not match the
// config is refused before any frame.
#include <doctest/doctest.h>

#include <bit>
#include <cstring>
#include <set>
#include <thread>

#include "core/camera.h"
#include "core/error.h"
#include "real_test_util.h"
#include "runtime_test_util.h"
#include "sim/run/real_replay.h"
#include "sim/run/runtime_setup.h"
#include "sim/trace/trace_gen.h"
#include "sim/view/scene.h"

// Threaded code: also run by the TSan variant of scripts/test.sh (ctest -L threads).
TEST_SUITE_BEGIN("threads");

using namespace vtsim;

namespace {

// The small VT store is 1024² texels (32 m at 32 texels/m), pages of 64 + 4-texel borders, two
// layers: 341 pages, all of which fit the default pool.
ReplayConfig runtime_vt_cfg(const std::vector<std::string>& sets = {}) {
  std::vector<std::string> all = {"texture.texels_per_m=32", "view.divisor=16"};
  all.insert(all.end(), sets.begin(), sets.end());
  return load_replay_config("", all, "vt");
}

Trace runtime_still(double seconds) {
  TraceGenParams g = default_gen_params("static");
  g.start_m = {16.0, 16.0};
  g.duration_s = seconds;
  g.image_width = 640;
  g.image_height = 360;
  return generate_trace(g);
}

}  // namespace

TEST_CASE("runtime (real clock): an engine's loop with a fake GPU ends with the real-clock replay's pages, byte-exact in their slots") {
  const TileStore store = TileStore::open(test::small_vt_store());
  const ReplayConfig cfg = runtime_vt_cfg();
  ReplayConfig bound = cfg;
  bind_store_texture(bound, store);
  auto scene = make_scene_from_config(bound);
  const Trace trace = runtime_still(1.0);

  // The engine: its feedback pass (here vtsim's renderer) on the still camera, frames paced at
  // ~1 ms until nothing is missing.
  auto rt = make_streaming_runtime(cfg, store);
  std::size_t slot_bytes = 0;
  for (std::uint32_t l = 0; l < store.layer_count(); ++l) slot_bytes = std::max<std::size_t>(slot_bytes, store.tile_bytes(l));
  test::FakeGpu gpu(static_cast<int>(store.layer_count()), bound.vt.pool_pages, slot_bytes);
  const Pose& pose = trace.poses.front();
  SpanBuffer fb;
  fb.block_shift = std::bit_width(static_cast<unsigned>(bound.texture.tile_size)) - 1;
  scene->render_spans(make_camera(pose, trace.image_width, trace.image_height), view_params(bound.view), fb);
  int frames = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  for (; std::chrono::steady_clock::now() < deadline; ++frames) {
    rt->begin_frame(rt->executor().now());
    rt->set_camera(pose);
    rt->set_feedback(fb, frames == 0);
    const FrameUpdates& u = rt->end_frame(gpu);
    gpu.apply(u);
    if (frames > 0 && rt->needs() == 0 && u.uploads == 0 && rt->pipeline().live_requests() == 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  INFO("frames " << frames);
  std::vector<std::pair<TileKey, std::uint32_t>> pages;
  rt->system().pool_pages(pages);
  REQUIRE(pages.size() > 20);

  // The real-clock replay of the same camera.
  const RealRun run = run_real_replay(bound, trace, *scene, store);
  std::set<TileKey> engine_pages, replay_pages;
  for (const auto& p : pages) engine_pages.insert(p.first);
  for (const auto& p : run.pool_pages) replay_pages.insert(p.first);
  CHECK(engine_pages == replay_pages);
  CHECK(gpu.uploads == run.result.summary["bandwidth"]["uploads"].get<std::uint64_t>());

  // The page table the updates built maps each page at its slot, and the slot holds its texels.
  std::map<TileKey, std::int64_t> want;
  for (const auto& [page, slot] : pages) want[page] = slot;
  CHECK(gpu.page_table == want);
  std::size_t compared = 0;
  for (const auto& [page, slot] : pages)
    for (std::uint32_t l = 0; l < store.layer_count(); ++l) {
      const std::vector<std::uint8_t> ref = test::decoded(store, TileKey(l, page.level(), page.x(), page.y()));
      CHECK(std::memcmp(gpu.slot_texels(slot, l), ref.data(), ref.size()) == 0);
      ++compared;
    }
  CHECK(compared == pages.size() * store.layer_count());
}

TEST_CASE("runtime (real clock): a store that does not match the config is refused at creation, naming the field") {
  const TileStore store = TileStore::open(test::small_vt_store());
  try {
    (void)make_streaming_runtime(runtime_vt_cfg({"texture.tile_size=32"}), store);
    FAIL("no exception");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("texture.tile_size") != std::string::npos);
  }
  try {
    (void)make_streaming_runtime(runtime_vt_cfg({"texture.width=2048", "texture.height=2048"}), store);
    FAIL("no exception");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("texture.width") != std::string::npos);
  }
}
TEST_SUITE_END();
