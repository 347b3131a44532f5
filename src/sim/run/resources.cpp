#include "sim/run/resources.h"

#include <algorithm>
#include <string>

#include "cache/clipmap.h"
#include "cache/page_table.h"
#include "sim/run/systems.h"
#include "stream/system/terrain_system.h"
#include "stream/system/vt_system.h"

namespace vtsim {

nlohmann::json resources_json(const ReplayConfig& cfg, const IStreamingSystem& system, const nlohmann::json& system_stats,
                              const MetricsCollector& metrics) {
  const TextureExtent extent{cfg.texture.width, cfg.texture.height};
  double bytes_per_texel = 0;
  std::uint64_t tile_disk = 0;
  for (const LayerSpec& l : cfg.texture.layers.specs) {
    bytes_per_texel += l.bytes_per_texel;
    tile_disk += tile_disk_bytes(cfg, l);
  }
  const auto* terrain = dynamic_cast<const TerrainSystem*>(&system);
  // VRAM sampled from: the VT's physical pool, or the clipmap's stack windows and pyramid (the
  // formula of `vtsim capacity`, docs/clipmap.md).
  std::uint64_t vram_texture = 0;
  if (dynamic_cast<const VtSystem*>(&system) != nullptr) {
    vram_texture = system_stats.value("pool_bytes", std::uint64_t{0});
  } else {
    const ClipmapMemory m = clipmap_memory(extent, cfg.texture.tile_size, cfg.clipmap.clipsize);
    vram_texture = static_cast<std::uint64_t>(static_cast<double>(m.stack_texels + m.pyramid_texels) * bytes_per_texel);
  }
  // The terrain's brush mips resident to render: the peak of its per-frame counter (MiB, exact).
  std::uint64_t brush_peak = 0;
  std::size_t brush_col = 0;
  const std::vector<std::string> cols = system.frame_counter_names();
  for (; brush_col < cols.size() && cols[brush_col] != "terrain_brush_MiB"; ++brush_col) {
  }
  std::uint64_t ram_peak = 0;
  std::vector<double> produce_ms;
  produce_ms.reserve(metrics.frames().size());
  for (const FrameRow& r : metrics.frames()) {
    ram_peak = std::max(ram_peak, r.ram_bytes);
    produce_ms.push_back(r.produce_ms);
    if (terrain && brush_col < cols.size())
      brush_peak = std::max(brush_peak, static_cast<std::uint64_t>(r.system[brush_col] * 1048576.0 + 0.5));
  }
  // Bytes on disk: the tile store under the codec model (every level the system needs, tiles with
  // their borders), or for the terrain what it produces from: every stored brush mip and the masks.
  std::uint64_t disk_stored = 0;
  if (terrain) {
    const TerrainCapacity c = terrain_capacity(cfg.terrain, cfg.texture.texels_per_m, cfg.clipmap.clipsize, 0.0, 0.0);
    disk_stored = static_cast<std::uint64_t>(static_cast<double>(c.brush_bytes_all_mips) / cfg.terrain.brush_compression) +
                  c.mask_bytes;
  } else {
    const VtGeometry g(extent, cfg.texture.tile_size, cfg.texture.border);
    std::uint64_t tiles = g.total_pages();
    if (const SystemInfo* info = streaming_systems().find(cfg.run.system))
      tiles += static_cast<std::uint64_t>(std::max(0, info->store_levels(cfg) - g.levels()));  // one tile per level below a tile
    disk_stored = tiles * tile_disk;
  }
  const Percentiles p = percentiles(std::move(produce_ms));
  return {{"vram_bytes", vram_texture + brush_peak},
          {"vram_texture_bytes", vram_texture},
          {"vram_brush_bytes_peak", brush_peak},
          {"ram_cache_bytes", static_cast<std::uint64_t>(cfg.ram.capacity_MiB * 1048576.0)},
          {"ram_peak_bytes", ram_peak},
          {"disk_stored_bytes", disk_stored},
          {"produce_ms_per_frame", {{"mean", p.mean}, {"p95", p.p95}, {"max", p.max}}}};
}

}  // namespace vtsim
