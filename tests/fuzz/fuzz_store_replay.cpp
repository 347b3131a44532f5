// A tile store read by the real clock (docs/real-engine.md): the store bound to a clipmap and to a
// virtual-texturing config, then three frames replayed with real IO and decode threads (faults
// injected on top) at 100× speed. A store that opens must replay: a tile that fails its
// checksum, decode or read is retried, then counted as failed, and the frame loop goes on.
#include <string>
#include <vector>

#include "fuzz_targets.h"
#include "sim/real_replay.h"
#include "sim/replay_config.h"
#include "sim/scene.h"
#include "sim/trace_transform.h"
#include "stream/tile_store.h"

namespace vtsim::fuzz {

void store_replay(const std::uint8_t* data, std::size_t size) {
  const std::string path = input_file(data, size, "vts");
  for (const char* system : {"clipmap", "vt"}) {
    expect_accept_or_reject("store_replay", [&] {
      const TileStore store = TileStore::open(path);
      // A clip window of 4 tiles (the default 1024 texels is not a multiple of every tile size),
      // checked against the store's tile size, which binding would take anyway.
      const std::string tile = std::to_string(store.geometry().tile);
      const std::string clipsize = "clipmap.clipsize=" + std::to_string(4 * std::uint64_t{store.geometry().tile});
      ReplayConfig cfg = load_replay_config("", {"texture.texels_per_m=1", "io.threads=2", "decode.workers=1",
                                                 "io.fault_rate=0.1", "io.fault.checksum_rate=0.1", "io.max_retries=1",
                                                 "vt.pool_pages=64", "texture.tile_size=" + tile, clipsize},
                                            system);
      (void)bind_store_texture(cfg, store);
      const auto scene = make_scene_from_config(cfg);
      Trace t;
      t.image_width = 64;
      t.image_height = 36;
      const double cx = static_cast<double>(store.geometry().width) * 0.5,
                   cy = static_cast<double>(store.geometry().height) * 0.5;
      for (int k = 0; k < 3; ++k) {
        Pose p;
        p.t_s = k / 60.0;
        p.pos_m = {cx, cy, 2.0 + k};
        p.q = yaw_pitch_quat(0.0, -60.0);
        t.poses.push_back(p);
      }
      apply_speed(cfg, t, 100.0);
      RealClockOptions o;
      o.memory_limit_bytes = std::uint64_t{256} << 20;
      (void)run_real_replay(cfg, t, *scene, store, o);
    });
  }
}

}  // namespace vtsim::fuzz
