#pragma once
// The produce stage (procedural virtual texturing): a tile that comes from a producer instead of
// the store. VT Terrain Design (after Chen 2015, Far Cry 4): the terrain's clipmap levels are
// rendered from tiling brush textures blended through masks, plus decals, so nothing of the
// ~364 TiB of texels is stored. docs/produced.md.
//
// A streaming system says which of its tiles are produced (IStreamingSystem::produced) and how much
// work each one is; the pipeline then skips the disk and the decode for it and runs the work on a
// production server (the simulated clock: ProduceModel below; the real clock: a CPU compositor on
// the decode workers), within a per-frame production budget (as Unreal's
// r.VT.MaxTilesProducedPerFrame), with the upload budget after it.
#include <cstdint>

namespace vtsim {

// The work of producing one tile: what the cost model and the compositor both count.
struct ProduceWork {
  std::uint64_t texels = 0;  // output texels (payload plus border); 0 = not produced (read from the store)
  std::uint32_t layers = 0;  // brush layers blended per texel (the sum over the sectors it covers, weighted by area)
  std::uint32_t decals = 0;  // decals overlapping the tile, each rendered over it
  std::uint64_t decal_texels = 0;  // output texels the decals touch, summed over them (each blended once per decal)
  bool produced() const { return texels != 0; }
};

// Simulated production (the config's [produce] section): `workers` identical servers; a tile takes
// per_tile_us + texels * (per_texel_ns + layers * per_layer_texel_ns) / 1000 + decals * per_decal_us
// + decal_texels * per_decal_texel_ns / 1000.
// The defaults are placeholders until `vtsim calibrate` measures the compositor (docs/produced.md).
struct ProduceModel {
  double per_tile_us = 10.0;         // fixed cost per tile (setup, mask fetch), us
  double per_texel_ns = 1.0;         // per output texel, independent of layers (store, pack), ns
  double per_layer_texel_ns = 1.0;   // per output texel per blended layer (sample + weight), ns
  double per_decal_us = 2.0;         // per decal rendered over the tile (its coverage rows), us
  double per_decal_texel_ns = 2.4;   // per output texel a decal touches (one alpha blend), ns (calibrate --produce, 2026-12-05: 2.37-2.48)
  int workers = 2;                   // production servers (the decode workers in the real clock); 0 = unlimited
  int tiles_per_frame = 0;           // production budget, tiles started per frame; 0 = unlimited (r.VT.MaxTilesProducedPerFrame)
};

// Production time of one tile under the model, in nanoseconds (the simulated executor rounds to ticks).
inline double produce_ns(const ProduceModel& m, const ProduceWork& w) {
  return m.per_tile_us * 1000.0 +
         static_cast<double>(w.texels) * (m.per_texel_ns + static_cast<double>(w.layers) * m.per_layer_texel_ns) +
         static_cast<double>(w.decals) * m.per_decal_us * 1000.0 + static_cast<double>(w.decal_texels) * m.per_decal_texel_ns;
}

}  // namespace vtsim
