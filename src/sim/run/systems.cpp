#include "sim/run/systems.h"

#include "core/error.h"
#include "stream/system/clipmap_system.h"
#include "stream/system/terrain_system.h"
#include "stream/system/vt_system.h"

namespace vtsim {

const Registry<SystemInfo>& streaming_systems() {
  static const Registry<SystemInfo> table(
      "streaming system",
      {
          system_entry<ClipmapSystem, &ReplayConfig::clipmap>(
              "clipmap (Tanner 1998, Yao 2007): toroidal windows that follow the camera over a static mip pyramid"),
          system_entry<VtSystem, &ReplayConfig::vt>(
              "sparse virtual texturing (van Waveren 2009, Yao 2011): feedback-driven pages in a physical page pool"),
          clipmap_system_entry<TerrainSystem, &ReplayConfig::terrain>(
              "VT Terrain Design's terrain (after Chen 2015, Far Cry 4): a clipmap whose levels are produced from brushes and masks"),
      });
  return table;
}

SystemSetup system_setup(const ReplayConfig& c) { return system_setup(c, {c.texture.width, c.texture.height}); }

SystemSetup system_setup(const ReplayConfig& c, TextureExtent extent) {
  SystemSetup s;
  s.extent = extent;
  s.tile_size = c.texture.tile_size;
  s.border = c.texture.border;
  s.layers = static_cast<int>(c.texture.layers.specs.size());
  for (const LayerSpec& l : c.texture.layers.specs) s.tile_bytes_all_layers += tile_decoded_bytes(c, l);
  s.texels_per_m = c.texture.texels_per_m;
  s.origin_x_m = c.texture.origin_x_m;
  s.origin_y_m = c.texture.origin_y_m;
  s.prefetch_lookahead_s = c.prefetch.lookahead_s;
  s.thrash_frames = c.metrics.thrash_frames;
  return s;
}

std::unique_ptr<IStreamingSystem> make_system(const ReplayConfig& c, TextureExtent extent) {
  const SystemInfo* info = streaming_systems().find(c.run.system);
  if (!info) throw InputError("config", "field 'run.system': " + streaming_systems().unknown(c.run.system));
  return info->make(c, extent);
}

}  // namespace vtsim
