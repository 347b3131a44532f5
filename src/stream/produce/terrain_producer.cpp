#include "stream/produce/terrain_producer.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"
#include "stream/produce/brush_images.h"

namespace vtsim::produce {

namespace {

ProduceScene terrain_scene(const TerrainProducerParams& p) {
  if (p.brush_files.empty()) return ProduceScene(p.brushes_per_sector, p.brush_size, p.brushes_per_sector, p.mask_size, p.sector_m, p.seed);
  const std::vector<std::string> files = expand_brush_files(p.brush_files);
  if (static_cast<int>(files.size()) != p.brushes_per_sector)
    throw InputError("config", fmt::format("field 'terrain.brush_files': {} brush image{} for terrain.brushes_per_sector = {} (one per "
                                           "brush a sector blends)",
                                           files.size(), files.size() == 1 ? "" : "s", p.brushes_per_sector));
  std::vector<Rgba8> brushes;
  for (const std::string& f : files) {
    brushes.push_back(read_brush(f));
    const Rgba8& b = brushes.back();
    if (b.width != p.brush_size || b.height != p.brush_size)
      throw InputError(f, fmt::format("brush is {}×{}; terrain.brush_size is {} (the brush mips the terrain streams are that size)",
                                      b.width, b.height, p.brush_size));
  }
  return ProduceScene(brushes, files, p.brushes_per_sector, p.mask_size, p.sector_m, p.seed);
}

}  // namespace

TerrainProducer::TerrainProducer(const TerrainProducerParams& p) : p_(p), scene_(terrain_scene(p)) {
  if (p.tile < 1 || p.border < 0 || p.width == 0 || p.height == 0 || !(p.texels_per_m > 0) || !(p.sector_m > 0))
    throw InputError("terrain producer", fmt::format("texture {}×{}, tile {}, border {}, {} texels/m, sector {} m", p.width, p.height,
                                                     p.tile, p.border, p.texels_per_m, p.sector_m));
  if (p.brush_tree_levels < 1 || p.brush_tree_levels > scene_.atlas().max_level() + 1)
    throw InputError("terrain producer", fmt::format("{} brush quadtree levels for a {}² brush", p.brush_tree_levels, p.brush_size));
}

std::uint64_t TerrainProducer::brush_bytes(int mip) const {
  // The quadtree's root carries the mips below it down to 1×1 (TerrainSystem::tile_sizes).
  const int last = mip == p_.brush_tree_levels - 1 ? std::countr_zero(static_cast<unsigned>(p_.brush_size)) : mip;
  std::uint64_t b = 0;
  for (int k = mip; k <= last; ++k) {
    const std::uint64_t side = static_cast<std::uint64_t>(std::max(1, p_.brush_size >> k));
    b += 4 * side * side;
  }
  return b;
}

void TerrainProducer::produce(const TileJob& job, TileData& out) {
  if (job.key.layer() == p_.brush_layer) {
    serve_brush(job, out);
    ++brushes_;
    brush_bytes_ += out.bytes;
    return;
  }
  if (!job.produce.produced())
    throw std::logic_error(fmt::format("TerrainProducer: tile (layer {}, level {}) is neither produced nor a brush mip", job.key.layer(),
                                       job.key.level()));
  if (!record_) {
    compose_tile(job, out);
    ++tiles_;
    return;
  }
  const auto w0 = std::chrono::steady_clock::now();
  const std::int64_t c0 = thread_cpu_ns();
  compose_tile(job, out);
  ++tiles_;
  {
    const std::int64_t c1 = thread_cpu_ns();
    const double wall = static_cast<double>(std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - w0).count());
    const std::lock_guard<std::mutex> lock(record_mutex_);
    recorded_.push_back(ProducedTile{job.key.level(), job.produce, wall, static_cast<double>(c1 - c0)});
  }
}

std::vector<ProducedTile> TerrainProducer::recorded_tiles() const {
  const std::lock_guard<std::mutex> lock(record_mutex_);
  return recorded_;
}

void TerrainProducer::compose_tile(const TileJob& job, TileData& out) const {
  // Per thread: the compositor's scratch rows, a payload buffer for partial tiles, the job's layer
  // and mask descriptors (compositor.h: one Compositor per thread).
  thread_local Compositor comp;
  thread_local std::vector<std::uint8_t> part;
  thread_local std::array<BrushLayer, kMaxLayers> layers;
  thread_local std::array<WeightMask, kMaxLayers / 4> masks;
  thread_local std::vector<Decal> decals;

  const int l = static_cast<int>(job.key.level());
  const std::int64_t T = p_.tile, B = p_.border;
  const std::int64_t lw = static_cast<std::int64_t>((p_.width + (std::uint64_t{1} << l) - 1) >> l);
  const std::int64_t lh = static_cast<std::int64_t>((p_.height + (std::uint64_t{1} << l) - 1) >> l);
  const std::int64_t w = std::clamp<std::int64_t>(lw - static_cast<std::int64_t>(job.key.x()) * T, 0, T);
  const std::int64_t h = std::clamp<std::int64_t>(lh - static_cast<std::int64_t>(job.key.y()) * T, 0, T);
  if (w == 0 || h == 0)
    throw std::logic_error(fmt::format("TerrainProducer: tile (level {}, x {}, y {}) is outside its level", l, job.key.x(), job.key.y()));

  // As bench_produce: the level's texel in metres, the tile's corner, the masks at its sector's corner.
  const double texel_m = std::exp2(l) / p_.texels_per_m, span_m = static_cast<double>(T) * texel_m;
  const double x = static_cast<double>(job.key.x()) * span_m, y = static_cast<double>(job.key.y()) * span_m;
  const double sx = std::floor(x / p_.sector_m) * p_.sector_m, sy = std::floor(y / p_.sector_m) * p_.sector_m;
  const int nl = std::clamp(static_cast<int>(job.produce.layers), 1, p_.brushes_per_sector);

  const std::size_t side = static_cast<std::size_t>(T + 2 * B);
  out.side = static_cast<std::uint32_t>(side);
  out.channels = 4;
  out.bytes = side * side * 4;
  // A full tile's composition writes every byte; a partial tile's unused texels are zeroed. (The
  // zeroing of every tile's 256 KiB was ~9 % of a real replay's CPU, perf 2026-12-06.)
  const bool full = w == T && h == T;
  out.texels = full ? std::make_unique_for_overwrite<std::uint8_t[]>(out.bytes) : std::make_unique<std::uint8_t[]>(out.bytes);
  // The decals over what is composed (border included): the layer's rule, the compositor re-checks.
  const auto with_decals = [&](CompositeJob j) {
    decals.clear();
    if (decals_) {
      const double x0 = x - j.border * texel_m, y0 = y - j.border * texel_m, n_m = (j.tile + 2 * j.border) * texel_m;
      decals_->collect(texel_m, x0, y0, x0 + n_m, y0 + n_m, decals);
      decals_drawn_ += static_cast<std::uint64_t>(
          std::count_if(decals.begin(), decals.end(), [&](const Decal& d) { return decal_drawn(d, texel_m, x0, y0, x0 + n_m, y0 + n_m); }));
    }
    j.decals = decals;
    return j;
  };
  if (full) {
    comp.compose(with_decals(scene_.job_into(layers, masks, nl, p_.brush_period_m, x, y, sx, sy, texel_m, p_.tile, p_.border)),
                 out.texels.get());
    return;
  }
  // A coarse level smaller than a tile: its payload only (square: the compositor's tiles are), at
  // the payload's place in the slot.
  const std::size_t s = static_cast<std::size_t>(std::max(w, h));
  part.resize(s * s * 4);
  comp.compose(with_decals(scene_.job_into(layers, masks, nl, p_.brush_period_m, x, y, sx, sy, texel_m, static_cast<int>(s), 0)),
               part.data());
  for (std::size_t r = 0; r < s; ++r)
    std::memcpy(out.texels.get() + ((static_cast<std::size_t>(B) + r) * side + static_cast<std::size_t>(B)) * 4, part.data() + r * s * 4, s * 4);
}

void TerrainProducer::serve_brush(const TileJob& job, TileData& out) const {
  const int mip = static_cast<int>(job.key.level());
  const int brush = static_cast<int>(job.key.y());
  const Atlas& a = scene_.atlas();
  if (mip >= p_.brush_tree_levels || brush >= p_.brushes_per_sector)
    throw std::logic_error(fmt::format("TerrainProducer: brush mip {} of brush {} is not in the scene", mip, brush));
  const int last = mip == p_.brush_tree_levels - 1 ? std::min(a.max_level(), std::countr_zero(static_cast<unsigned>(p_.brush_size))) : mip;
  out.side = static_cast<std::uint32_t>(std::max(1, p_.brush_size >> mip));
  out.channels = 4;
  out.bytes = static_cast<std::size_t>(brush_bytes(mip));
  out.texels = std::make_unique_for_overwrite<std::uint8_t[]>(out.bytes);
  std::size_t at = 0;
  for (int k = mip; k <= last; ++k) {
    const AtlasLevel& lv = a.levels[static_cast<std::size_t>(k)];
    const std::size_t row = static_cast<std::size_t>(lv.brush_side) * 4;
    for (int r = 0; r < lv.brush_side; ++r, at += row) std::memcpy(out.texels.get() + at, lv.texel(a.cols, brush, 0, r), row);
  }
  if (at != out.bytes)
    throw std::logic_error(fmt::format("TerrainProducer: brush mip {} filled {} of {} bytes", mip, at, out.bytes));
}

}  // namespace vtsim::produce
