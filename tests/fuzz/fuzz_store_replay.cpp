// A tile store read by the real clock (docs/real-engine.md): the store bound to a clipmap and to a
// virtual-texturing config, then three frames replayed with real IO and decode threads (faults
// injected on top) at 100× speed. A store that opens must replay: a tile that fails its
// checksum, decode or read is retried, then counted as failed, and the frame loop goes on.
#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/error.h"
#include "fuzz_targets.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay_config.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_transform.h"
#include "stream/store/tile_store.h"

namespace vtsim::fuzz {

namespace {

// The real clock's own refusal of a config whose buffers do not fit in host memory (a store can
// legitimately have tiles too large for the RAM cache or the VRAM arena); every other error of
// the replay is a finding.
bool memory_refusal(const InputError& e) {
  const std::string what = e.what();
  return what.find("'ram.capacity_MiB': the RAM cache's buffers need") != std::string::npos ||
         what.find(": the VRAM arena") != std::string::npos;
}

}  // namespace

void store_replay(const std::uint8_t* data, std::size_t size) {
  const std::string path = input_file(data, size, "vts");
  for (const char* system : {"clipmap", "vt"}) {
    std::optional<TileStore> store;
    ReplayConfig cfg;
    std::unique_ptr<IScene> scene;
    Trace t;
    expect_accept_or_reject("store_replay", [&] {
      store.emplace(TileStore::open(path));
      cfg = load_replay_config("", {"texture.texels_per_m=1", "io.threads=2", "decode.workers=1", "io.fault_rate=0.1",
                                    "io.fault.checksum_rate=0.1", "io.max_retries=1", "vt.pool_pages=64",
                                    "ram.capacity_MiB=16"},
                               system);
      // A clip window of 4 tiles (the default 1024 texels is not a multiple of every tile size);
      // set directly, as texture.tile_size's range would refuse the store's tiny tiles, which
      // binding takes from the store (and validates again).
      cfg.clipmap.clipsize = static_cast<int>(std::min<std::uint64_t>(4 * std::uint64_t{store->geometry().tile}, 1 << 20));
      (void)bind_store_texture(cfg, *store);
      scene = make_scene_from_config(cfg);
      t.image_width = 64;
      t.image_height = 36;
      const double cx = static_cast<double>(store->geometry().width) * 0.5,
                   cy = static_cast<double>(store->geometry().height) * 0.5;
      for (int k = 0; k < 3; ++k) {
        Pose p;
        p.t_s = k / 60.0;
        p.pos_m = {cx, cy, 2.0 + k};
        p.q = yaw_pitch_quat(0.0, -60.0);
        t.poses.push_back(p);
      }
      apply_speed(cfg, t, 100.0);
    });
    if (!scene) continue;
    must_succeed("store_replay", "the real-clock replay of a bound store", [&] {
      RealClockOptions o;
      o.memory_limit_bytes = std::uint64_t{256} << 20;
      try {
        (void)run_real_replay(cfg, t, *scene, *store, o);
      } catch (const InputError& e) {
        if (!memory_refusal(e)) throw;
      }
    });
  }
}

}  // namespace vtsim::fuzz
