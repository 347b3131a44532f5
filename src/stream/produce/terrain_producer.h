#pragma once
// The real clock's producer for the produced terrain (run.system = "terrain"; docs/produced.md,
// "The real clock"): composes each produced tile with the CPU compositor (compositor.h) on the
// executor's production threads, and serves the terrain's brush mips (TerrainSystem::kBrushLayer
// keys) from memory.
//
// Content: the scene bench_produce composes (ProduceScene: brushes in a constant-border atlas, 4
// RGBA8 masks whose first brushes_per_sector channels are non-zero everywhere), built once from the
// replay's [terrain] figures and a fixed seed, so a run is reproducible: brushes_per_sector brushes
// of brush_size², one mask set of mask_size² texels over a sector, placed at every sector's corner.
// The brushes are value noise, or the images terrain.brush_files names (any format OpenImageIO
// reads; one per brush, each brush_size² — refused otherwise, naming the file and the field).
// Every sector blends the same brushes (the terrain's brush keys name a sector's brush; its texels
// are the atlas's cell `brush`); the work (texels × layers) is what the cost model counts.
//
// A tile (layer < kBrushLayer, level l, x, y) is composed as bench_produce composes it: output
// texel m_per_texel = 2^l / texels_per_m, payload texel (0, 0) at (x, y) · T · m_per_texel metres,
// the masks at the corner of the sector holding that point, brush period brush_period_m,
// work.layers layers, and the decals of the system's DecalLayer over it (set_decals; none when
// unset) drawn over the blend. A full tile
// is composed with the texture's border (T + 2B a side, what the VRAM arena's slot holds); a
// coarse level's partial tile (its level smaller than a tile) composes only its payload texels, as
// the model counts them, into the slot's top-left with the rest zero. Every layer is rgba8 (checked
// by the caller) and composed alike.
//
// A brush mip (kBrushLayer, level = mip, x = sector, y = brush) is served, not read: its decoded
// bytes (4 · (brush_size >> mip)², the quadtree root with its tail) copied from the atlas's cell,
// level by level — the stand-in for its read and decode, which this design does not time.
//
// Thread-safety: produce() and serves() may run on any number of threads at once: the scene is
// immutable after the constructor; each thread has its own Compositor and scratch (thread_local).
// Counters are atomics; recorded tiles are appended under a mutex (once a tile: ~1 ms of work
// each, so never contended). set_decals and record_tiles must happen before the first produce() (the real replay calls
// it from ReplayEnv::on_start, before frame 0); the layer itself takes appends while threads read.
// A tile drawn later than its request may show footprints placed since: the freshest, as a game's.
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "stream/exec/i_producer.h"
#include "stream/produce/decal_layer.h"
#include "stream/produce/produce_calibrate.h"

namespace vtsim::produce {

struct TerrainProducerParams {
  std::uint64_t width = 0, height = 0;  // level-0 texels (texture.width, .height)
  int tile = 256, border = 0;           // texture.tile_size, texture.border
  double texels_per_m = 1024;           // texture.texels_per_m
  int brushes_per_sector = 12;          // terrain.*
  int brush_size = 1024;
  double brush_period_m = 1.0;
  int brush_tree_levels = 5;
  int mask_size = 512;
  double sector_m = 512;
  std::uint32_t brush_layer = 15;       // TerrainSystem::kBrushLayer
  std::uint64_t seed = 7;               // the scene's content (bench_produce's)
  std::vector<std::string> brush_files;  // terrain.brush_files, split at commas: files or patterns; empty = value noise
};


class TerrainProducer final : public ITileProducer {
 public:
  // Builds the scene (~brushes_per_sector × brush_size² × 4/3 × a few ns, plus reading the brush
  // files). InputError on bad figures or brush files, naming the file and the field.
  explicit TerrainProducer(const TerrainProducerParams& p);
  void produce(const TileJob& job, TileData& out) override;
  bool serves(const TileJob& job) const override { return job.key.layer() == p_.brush_layer; }
  void set_decals(std::shared_ptr<const DecalLayer> decals) { decals_ = std::move(decals); }
  // Keep a ProducedTile for every composed tile (not brush mips), in completion order; before the
  // first produce(). ~48 bytes a tile.
  void record_tiles(bool on) { record_ = on; }
  std::vector<ProducedTile> recorded_tiles() const;

  // Decoded bytes of brush mip `mip` (the root's tail included), as TerrainSystem sizes it.
  std::uint64_t brush_bytes(int mip) const;
  const ProduceScene& scene() const { return scene_; }
  std::uint64_t tiles() const { return tiles_.load(std::memory_order_relaxed); }
  std::uint64_t brushes() const { return brushes_.load(std::memory_order_relaxed); }
  std::uint64_t brush_bytes_served() const { return brush_bytes_.load(std::memory_order_relaxed); }
  std::uint64_t decals_drawn() const { return decals_drawn_.load(std::memory_order_relaxed); }  // summed over tiles

 private:
  void compose_tile(const TileJob& job, TileData& out) const;
  void serve_brush(const TileJob& job, TileData& out) const;

  TerrainProducerParams p_;
  ProduceScene scene_;
  std::shared_ptr<const DecalLayer> decals_;
  mutable std::atomic<std::uint64_t> decals_drawn_{0};
  std::atomic<std::uint64_t> tiles_{0}, brushes_{0}, brush_bytes_{0};
  bool record_ = false;
  mutable std::mutex record_mutex_;
  std::vector<ProducedTile> recorded_;  // guarded by record_mutex_
};

}  // namespace vtsim::produce
