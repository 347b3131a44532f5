#include "stream/system/terrain_system.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include <fmt/format.h>

#include "core/error.h"
#include "stream/system/clipmap_system.h"

namespace vtsim {

namespace {

[[noreturn]] void bad_terrain_field(const std::string& key, const std::string& what) {
  throw InputError("config", "field '" + key + "': " + what);
}

constexpr double kMaxFootprintStep_m = 50.0;  // a longer frame-to-frame jump is a cut, not a walk

// Sector texels a side, or -1 when sector_m × texels_per_m is not an integer.
std::int64_t sector_texels_of(const TerrainConfig& t, double texels_per_m) {
  const double st = t.sector_m * texels_per_m;
  const double r = std::round(st);
  return (r >= 1.0 && std::fabs(st - r) <= 1e-9 * r) ? static_cast<std::int64_t>(r) : -1;
}

// log2(brush texel density / texture density), or -1 when it is not a power of two >= 1.
int mip_offset_of(const TerrainConfig& t, double texels_per_m) {
  const double ratio = static_cast<double>(t.brush_size) / (t.brush_period_m * texels_per_m);
  const double l = std::round(std::log2(ratio));
  if (l < 0 || std::fabs(ratio - std::exp2(l)) > 1e-9 * ratio) return -1;
  return static_cast<int>(l);
}

std::uint64_t brush_mip_bytes(int brush_size, int mip, int tree_levels) {
  // The coarsest stored mip (the quadtree's root) carries its tail down to 1×1.
  const int last = mip == tree_levels - 1 ? std::countr_zero(static_cast<unsigned>(brush_size)) : mip;
  std::uint64_t b = 0;
  for (int k = mip; k <= last; ++k) {
    const std::uint64_t side = static_cast<std::uint64_t>(std::max(1, brush_size >> k));
    b += 4 * side * side;
  }
  return b;
}

}  // namespace

void TerrainSystem::validate(const SystemSetup& s, const ClipmapConfig& cc, const TerrainConfig& t, const ThrottleParams& th) {
  ClipmapSystem::validate(s, cc, th);
  if (t.brushes_per_sector < 1 || t.brushes_per_sector > kMaxBrushes)
    bad_terrain_field("terrain.brushes_per_sector",
                      fmt::format("{} brushes: a sector blends 1 to {} (four RGBA masks, a 4×4 atlas)", t.brushes_per_sector, kMaxBrushes));
  if (t.brush_size < 1 || !std::has_single_bit(static_cast<unsigned>(t.brush_size)))
    bad_terrain_field("terrain.brush_size", fmt::format("{} is not a power of two", t.brush_size));
  const int mips = std::countr_zero(static_cast<unsigned>(t.brush_size)) + 1;
  if (t.brush_tree_levels < 1 || t.brush_tree_levels > mips)
    bad_terrain_field("terrain.brush_tree_levels",
                      fmt::format("{} levels: a {}² brush has {} mips (1 to {} quadtree levels)", t.brush_tree_levels, t.brush_size, mips, mips));
  const std::int64_t st = sector_texels_of(t, s.texels_per_m);
  if (st < 0)
    bad_terrain_field("terrain.sector_m", fmt::format("{} m × texture.texels_per_m {} is not a whole number of texels",
                                                      t.sector_m, s.texels_per_m));
  if (t.mask_size < 1 || st % t.mask_size != 0)
    bad_terrain_field("terrain.mask_size", fmt::format("{} does not divide the sector's {} texels (terrain.sector_m {} × "
                                                       "texture.texels_per_m {})", t.mask_size, st, t.sector_m, s.texels_per_m));
  if (s.extent.width != st * t.sectors_x)
    bad_terrain_field("texture.width", fmt::format("{} texels, but terrain.sectors_x {} × terrain.sector_m {} m × "
                                                   "texture.texels_per_m {} = {}", s.extent.width, t.sectors_x, t.sector_m,
                                                   s.texels_per_m, st * t.sectors_x));
  if (s.extent.height != st * t.sectors_y)
    bad_terrain_field("texture.height", fmt::format("{} texels, but terrain.sectors_y {} × terrain.sector_m {} m × "
                                                    "texture.texels_per_m {} = {}", s.extent.height, t.sectors_y, t.sector_m,
                                                    s.texels_per_m, st * t.sectors_y));
  if (mip_offset_of(t, s.texels_per_m) < 0)
    bad_terrain_field("texture.texels_per_m",
                      fmt::format("{}: the brush density terrain.brush_size {} / terrain.brush_period_m {} m must be the texture's "
                                  "density times a power of two >= 1", s.texels_per_m, t.brush_size, t.brush_period_m));
  if (t.decal_size_m > t.sector_m) bad_terrain_field("terrain.decal_size_m", fmt::format("{} m is larger than a sector", t.decal_size_m));
  if (t.footprint_size_m > t.sector_m)
    bad_terrain_field("terrain.footprint_size_m", fmt::format("{} m is larger than a sector", t.footprint_size_m));
  if (s.layers >= static_cast<int>(kBrushLayer))
    bad_terrain_field("texture.layers", fmt::format("{} layers: the terrain keeps layer {} for its brush mips", s.layers, kBrushLayer));
}

VramArena TerrainSystem::vram_arena(const SystemSetup& s, const ClipmapConfig& c, std::vector<std::uint32_t> layer_bytes,
                                    std::uint64_t host_limit) {
  return VramArena::for_clipmap(ClipmapSystem::params(s, c), std::move(layer_bytes), host_limit);
}

TerrainSystem::TerrainSystem(const SystemSetup& s, const ClipmapConfig& cc, const TerrainConfig& t)
    : ClipmapBacked(ClipmapSystem::params(s, cc)), s_(s), t_(t) {
  sector_texels_ = std::max<std::int64_t>(1, sector_texels_of(t, s.texels_per_m));
  sectors_ = t.sectors_x * t.sectors_y;
  mip_offset_ = std::max(0, mip_offset_of(t, s.texels_per_m));
  const std::size_t n = static_cast<std::size_t>(t.brush_tree_levels) * static_cast<std::size_t>(sectors_) * kMaxBrushes;
  resident_.assign(n, 0);
  needed_.assign(n, 0);
  emitted_frame_.assign(n, -1);
  produced_.assign(static_cast<std::size_t>(cm_.num_levels()), 0);
  decals_ = std::make_shared<produce::DecalLayer>(produce::DecalLayerParams{t.sectors_x, t.sectors_y, t.sector_m, t.decals_static,
                                                                             t.decal_size_m, t.decal_seed, t.footprint_size_m});
}

int TerrainSystem::brush_mip(int level) const { return std::min(level + mip_offset_, t_.brush_tree_levels - 1); }

std::uint64_t TerrainSystem::brush_decoded(int mip) const { return brush_mip_bytes(t_.brush_size, mip, t_.brush_tree_levels); }

void TerrainSystem::tile_sectors(int level, std::int64_t tx, std::int64_t ty, int& x0, int& x1, int& y0, int& y1) const {
  const std::int64_t span = static_cast<std::int64_t>(s_.tile_size) << level;  // level-0 texels per tile
  const std::int64_t u0 = tx * span, v0 = ty * span;
  const std::int64_t u1 = std::min(u0 + span, s_.extent.width) - 1, v1 = std::min(v0 + span, s_.extent.height) - 1;
  x0 = static_cast<int>(std::clamp<std::int64_t>(u0 / sector_texels_, 0, t_.sectors_x - 1));
  x1 = static_cast<int>(std::clamp<std::int64_t>(std::max(u0, u1) / sector_texels_, 0, t_.sectors_x - 1));
  y0 = static_cast<int>(std::clamp<std::int64_t>(v0 / sector_texels_, 0, t_.sectors_y - 1));
  y1 = static_cast<int>(std::clamp<std::int64_t>(std::max(v0, v1) / sector_texels_, 0, t_.sectors_y - 1));
}

void TerrainSystem::add_footprint(double x_m, double y_m) {
  if (!decals_->add_footprint(x_m, y_m)) ++footprints_dropped_;
  const double tpm = s_.texels_per_m;
  const std::int64_t u0 = static_cast<std::int64_t>(std::floor((x_m - t_.footprint_size_m / 2) * tpm));
  const std::int64_t u1 = static_cast<std::int64_t>(std::floor((x_m + t_.footprint_size_m / 2) * tpm));
  const std::int64_t v0 = static_cast<std::int64_t>(std::floor((y_m - t_.footprint_size_m / 2) * tpm));
  const std::int64_t v1 = static_cast<std::int64_t>(std::floor((y_m + t_.footprint_size_m / 2) * tpm));
  for (int l = 0; l < std::min(t_.footprint_levels, cm_.first_pyramid_level()); ++l) {
    const std::int64_t span = static_cast<std::int64_t>(s_.tile_size) << l;
    for (std::int64_t ty = std::max<std::int64_t>(0, v0) / span; ty <= std::max<std::int64_t>(0, v1) / span; ++ty)
      for (std::int64_t tx = std::max<std::int64_t>(0, u0) / span; tx <= std::max<std::int64_t>(0, u1) / span; ++tx) {
        bool any = false;
        for (int layer = 0; layer < s_.layers; ++layer) {
          const TileKey k(static_cast<std::uint32_t>(layer), static_cast<std::uint32_t>(l), tx, ty);
          if (cm_.resident(k)) any = dirty_.insert(k.bits).second || any;
        }
        if (any) ++invalidations_;
      }
  }
}

void TerrainSystem::begin_frame(const SystemFrame& f) {
  frame_ = f.frame;
  frame_produced_ = frame_brush_loads_ = frame_releases_ = frame_gated_ = 0;
  const double x = f.pose->pos_m.x - s_.origin_x_m, y = f.pose->pos_m.y - s_.origin_y_m;
  gu_ = static_cast<std::int64_t>(std::floor(x * s_.texels_per_m));
  gv_ = static_cast<std::int64_t>(std::floor(y * s_.texels_per_m));
  finest_active_ = std::min(f.finest_needed, cm_.num_levels());
  prefetch_ = s_.prefetch_lookahead_s > 0 && (f.velocity_mps.x != 0.0 || f.velocity_mps.y != 0.0);
  if (prefetch_) {
    fu_ = static_cast<std::int64_t>(std::floor((x + f.velocity_mps.x * s_.prefetch_lookahead_s) * s_.texels_per_m));
    fv_ = static_cast<std::int64_t>(std::floor((y + f.velocity_mps.y * s_.prefetch_lookahead_s) * s_.texels_per_m));
  }
  if (t_.footprint_every_m > 0) {
    if (have_last_) {
      const double step = std::hypot(x - last_x_, y - last_y_);
      if (step <= kMaxFootprintStep_m) travel_ += step;
      while (travel_ >= t_.footprint_every_m) {
        travel_ -= t_.footprint_every_m;
        add_footprint(x, y);
      }
    }
    have_last_ = true;
    last_x_ = x;
    last_y_ = y;
  }
}

void TerrainSystem::missing_bytes_by_level(std::vector<std::uint64_t>& out) const {
  cm_.missing_bytes_by_level(gu_, gv_, finest_active_, s_.tile_bytes_all_layers, out);
}

void TerrainSystem::recompute_needed() {
  std::fill(needed_.begin(), needed_.end(), std::uint8_t{0});
  for (int l = 0; l < cm_.num_levels(); ++l) {
    if (!cm_.window_placed(l)) continue;
    const bool pyramid = l >= cm_.first_pyramid_level();
    if (pyramid && cm_.level_complete(l)) continue;  // produced once: its brushes go
    const Clipmap::Window w = cm_.window(l);
    int x0, x1, y0, y1, a, b, c, d;
    tile_sectors(l, w.x0, w.y0, x0, a, y0, c);
    tile_sectors(l, w.x0 + w.w - 1, w.y0 + w.h - 1, b, x1, d, y1);
    const int m = brush_mip(l);
    for (int sy = y0; sy <= y1; ++sy)
      for (int sx = x0; sx <= x1; ++sx)
        for (int br = 0; br < t_.brushes_per_sector; ++br) needed_[idx(m, sy * t_.sectors_x + sx, br)] = 1;
  }
  for (int m = 0; m < t_.brush_tree_levels; ++m)
    for (int sec = 0; sec < sectors_; ++sec)
      for (int br = 0; br < t_.brushes_per_sector; ++br) {
        const std::size_t i = idx(m, sec, br);
        if (resident_[i] && !needed_[i]) {
          resident_[i] = 0;
          brush_bytes_ -= brush_decoded(m);
          ++brush_releases_;
          ++frame_releases_;
        }
      }
  needed_dirty_ = false;
}

void TerrainSystem::gate(const Need& n, std::vector<Need>& out, bool prefetch) {
  const int l = static_cast<int>(n.key.level()), m = brush_mip(l);
  int x0, x1, y0, y1;
  tile_sectors(l, n.key.x(), n.key.y(), x0, x1, y0, y1);
  bool ready = true;
  for (int sy = y0; sy <= y1; ++sy)
    for (int sx = x0; sx <= x1; ++sx)
      for (int br = 0; br < t_.brushes_per_sector; ++br) {
        const int sec = sy * t_.sectors_x + sx;
        const std::size_t i = idx(m, sec, br);
        if (resident_[i]) continue;
        ready = false;
        if (emitted_frame_[i] == frame_) continue;
        emitted_frame_[i] = frame_;
        out.push_back(Need{TileKey(kBrushLayer, static_cast<std::uint32_t>(m), sec, br), n.priority, prefetch});
      }
  if (ready) {
    if (!prefetch) out.push_back(n);
  } else if (!prefetch) {
    ++gated_;
    ++frame_gated_;
  }
}

void TerrainSystem::emit_needs(std::vector<Need>& out) {
  if (cm_.update_windows(gu_, gv_, finest_active_) > 0) needed_dirty_ = true;
  if (needed_dirty_) recompute_needed();
  tmp_.clear();
  cm_.emit_needs(finest_active_, [](int, std::int64_t, std::int64_t) { return std::uint64_t{0}; }, tmp_);
  const std::size_t demand = tmp_.size();
  for (auto it = dirty_.begin(); it != dirty_.end();) {
    TileKey key;
    key.bits = *it;
    if (!cm_.resident(key)) {  // left its window: the normal path asks for it when it returns
      it = dirty_.erase(it);
      continue;
    }
    tmp_.push_back(Need{key, make_priority(key.level(), 0, 0), false});
    ++it;
  }
  std::sort(tmp_.begin() + static_cast<std::ptrdiff_t>(demand), tmp_.end(),
            [](const Need& a, const Need& b) { return a.key < b.key; });  // unordered_set order is not deterministic
  for (const Need& n : tmp_) gate(n, out, false);
  if (prefetch_) {
    tmp_.clear();
    cm_.emit_prefetch(fu_, fv_, finest_active_, tmp_);
    for (const Need& n : tmp_) gate(n, out, true);
  }
}

bool TerrainSystem::accepts(TileKey key) const {
  if (key.layer() == kBrushLayer) {
    const int m = static_cast<int>(key.level());
    if (m >= t_.brush_tree_levels || key.x() >= sectors_ || key.y() >= t_.brushes_per_sector) return false;
    return needed_[idx(m, static_cast<int>(key.x()), static_cast<int>(key.y()))] != 0;
  }
  return cm_.accepts(key);
}

bool TerrainSystem::commit(TileKey key, int) {
  if (key.layer() == kBrushLayer) {
    const int m = static_cast<int>(key.level());
    if (m >= t_.brush_tree_levels || key.x() >= sectors_ || key.y() >= t_.brushes_per_sector) return false;
    const std::size_t i = idx(m, static_cast<int>(key.x()), static_cast<int>(key.y()));
    if (!needed_[i]) {
      ++stale_brush_commits_;
      return false;
    }
    if (!resident_[i]) {
      resident_[i] = 1;
      brush_bytes_ += brush_decoded(m);
      ++brush_loads_;
      ++frame_brush_loads_;
    }
    return true;
  }
  const int l = static_cast<int>(key.level());
  if (!cm_.commit(key)) return false;
  dirty_.erase(key.bits);
  if (key.layer() == 0) {
    ++produced_[static_cast<std::size_t>(l)];
    ++frame_produced_;
  }
  if (l >= cm_.first_pyramid_level() && cm_.level_complete(l)) needed_dirty_ = true;
  return true;
}

std::uint32_t TerrainSystem::count_decals(int level, std::int64_t tx, std::int64_t ty, std::uint64_t& texels) const {
  const double tpm = s_.texels_per_m;
  const double texel_m = std::exp2(level) / tpm;
  const double span_m = static_cast<double>(static_cast<std::int64_t>(s_.tile_size) << level) / tpm;
  const double x0 = static_cast<double>(tx) * span_m, y0 = static_cast<double>(ty) * span_m;
  return decals_->count(texel_m, x0, y0, x0 + span_m, y0 + span_m, texels);
}

bool TerrainSystem::produced(TileKey key, ProduceWork& work) const {
  if (key.layer() == kBrushLayer || static_cast<int>(key.level()) >= cm_.num_levels()) return false;
  const int l = static_cast<int>(key.level());
  const std::int64_t lw = (s_.extent.width + (std::int64_t{1} << l) - 1) >> l;
  const std::int64_t lh = (s_.extent.height + (std::int64_t{1} << l) - 1) >> l;
  const std::int64_t T = s_.tile_size;
  const std::int64_t w = std::clamp<std::int64_t>(lw - key.x() * T, 0, T), h = std::clamp<std::int64_t>(lh - key.y() * T, 0, T);
  work.texels = static_cast<std::uint64_t>(w * h);
  // Every texel blends the brushes of its own sector: area-weighted, brushes_per_sector everywhere
  // (sectors share a count); the sum over sectors is what the brush needs count (docs/produced.md).
  work.layers = static_cast<std::uint32_t>(t_.brushes_per_sector);
  work.decals = count_decals(l, key.x(), key.y(), work.decal_texels);
  return work.produced();
}

bool TerrainSystem::full_tile_work(ProduceWork& work) const {
  work.texels = static_cast<std::uint64_t>(s_.tile_size) * static_cast<std::uint64_t>(s_.tile_size);
  work.layers = static_cast<std::uint32_t>(t_.brushes_per_sector);
  work.decals = 0;
  work.decal_texels = 0;
  return true;
}

bool TerrainSystem::tile_sizes(TileKey key, std::uint64_t& disk_bytes, std::uint64_t& decoded_bytes) const {
  if (key.layer() != kBrushLayer || static_cast<int>(key.level()) >= t_.brush_tree_levels) return false;
  decoded_bytes = brush_decoded(static_cast<int>(key.level()));
  disk_bytes = static_cast<std::uint64_t>(std::ceil(static_cast<double>(decoded_bytes) / t_.brush_compression));
  return true;
}

std::vector<std::string> TerrainSystem::frame_counter_names() const {
  return {"terrain_tiles_produced", "terrain_brush_MiB", "terrain_brush_loads", "terrain_brush_releases",
          "terrain_gated_needs",    "terrain_decals",    "terrain_invalidations"};
}

void TerrainSystem::frame_counters(SystemCounters& out) const {
  out.fill(0.0);
  out[0] = frame_produced_;
  out[1] = static_cast<double>(brush_bytes_) / 1048576.0;
  out[2] = frame_brush_loads_;
  out[3] = frame_releases_;
  out[4] = frame_gated_;
  out[5] = static_cast<double>(decals_->statics() + decals_->footprints());
  out[6] = static_cast<double>(invalidations_);
}

std::uint64_t TerrainSystem::evicted_unsampled_bytes() const {
  return cm_.stats().evicted_unsampled * (s_.tile_bytes_all_layers / static_cast<std::uint64_t>(s_.layers));
}

nlohmann::json TerrainSystem::stats_json() const {
  std::vector<std::uint64_t> by_mip(static_cast<std::size_t>(t_.brush_tree_levels), 0);
  for (int m = 0; m < t_.brush_tree_levels; ++m)
    for (int sec = 0; sec < sectors_; ++sec)
      for (int br = 0; br < t_.brushes_per_sector; ++br)
        if (resident_[idx(m, sec, br)]) by_mip[static_cast<std::size_t>(m)] += brush_decoded(m);
  std::vector<int> mips;
  for (int l = 0; l < cm_.num_levels(); ++l) mips.push_back(brush_mip(l));
  const auto& s = cm_.stats();
  return {{"levels", cm_.num_levels()},
          {"stack_levels", cm_.first_pyramid_level()},
          {"window_moves", s.window_moves},
          {"vram_evictions", s.vram_evictions},
          {"tiles_produced_by_level", produced_},
          {"level_brush_mip", mips},
          {"brush_bytes_resident", brush_bytes_},
          {"brush_bytes_resident_by_mip", by_mip},
          {"brush_loads", brush_loads_},
          {"brush_releases", brush_releases_},
          {"stale_brush_commits", stale_brush_commits_},
          {"gated_needs", gated_},
          {"decals_static", decals_->statics()},
          {"footprints", decals_->footprints()},
          {"footprints_dropped", footprints_dropped_},
          {"invalidations", invalidations_}};
}

TerrainCapacity terrain_capacity(const TerrainConfig& t, double texels_per_m, int clipsize, double cam_x_m, double cam_y_m) {
  TerrainCapacity c;
  const std::int64_t st = sector_texels_of(t, texels_per_m);
  c.texels_side_x = st * t.sectors_x;
  c.texels_side_y = st * t.sectors_y;
  c.stored_equiv_bytes = static_cast<double>(c.texels_side_x) * static_cast<double>(c.texels_side_y) * 4.0;
  const std::uint64_t sectors = static_cast<std::uint64_t>(t.sectors_x) * static_cast<std::uint64_t>(t.sectors_y);
  c.brushes = sectors * static_cast<std::uint64_t>(t.brushes_per_sector);
  const std::uint64_t bs = static_cast<std::uint64_t>(t.brush_size);
  c.brush_bytes_mip0 = c.brushes * bs * bs * 4;
  const int mips = std::countr_zero(static_cast<unsigned>(t.brush_size)) + 1;
  for (int m = 0; m < mips; ++m) c.brush_bytes_all_mips += c.brushes * 4 * (bs >> m) * (bs >> m);
  c.masks = sectors * static_cast<std::uint64_t>((t.brushes_per_sector + 3) / 4);
  c.mask_bytes = c.masks * 4 * static_cast<std::uint64_t>(t.mask_size) * static_cast<std::uint64_t>(t.mask_size);
  const std::int64_t side = std::max(c.texels_side_x, c.texels_side_y);
  int stack = 0;
  while ((side >> stack) > clipsize) ++stack;
  c.full_levels = stack + 1;
  c.clipmap_full_levels_bytes = static_cast<std::uint64_t>(c.full_levels) * 4 * static_cast<std::uint64_t>(clipsize) *
                                static_cast<std::uint64_t>(clipsize);
  const int offset = std::max(0, mip_offset_of(t, texels_per_m));
  c.brush_resident_by_mip.assign(static_cast<std::size_t>(t.brush_tree_levels), 0);
  std::vector<int> most(static_cast<std::size_t>(t.brush_tree_levels), 0);
  const double cu = cam_x_m * texels_per_m, cv = cam_y_m * texels_per_m;
  for (int l = 0; l < stack; ++l) {
    const double half = static_cast<double>(clipsize) * std::exp2(l) / 2;  // level-0 texels
    const auto range = [&](double c0, int n) {
      const double lo = std::max(0.0, c0 - half), hi = std::min(static_cast<double>(st) * n, c0 + half);
      return static_cast<int>(std::ceil(hi / static_cast<double>(st))) - static_cast<int>(std::floor(lo / static_cast<double>(st)));
    };
    const int secs = range(cu, t.sectors_x) * range(cv, t.sectors_y);
    const int m = std::min(l + offset, t.brush_tree_levels - 1);
    c.level_mip.push_back(m);
    c.level_sectors.push_back(secs);
    most[static_cast<std::size_t>(m)] = std::max(most[static_cast<std::size_t>(m)], secs);
  }
  for (int m = 0; m < t.brush_tree_levels; ++m) {
    c.brush_resident_by_mip[static_cast<std::size_t>(m)] = static_cast<std::uint64_t>(most[static_cast<std::size_t>(m)]) *
                                                           static_cast<std::uint64_t>(t.brushes_per_sector) *
                                                           brush_mip_bytes(t.brush_size, m, t.brush_tree_levels);
    c.brush_resident_bytes += c.brush_resident_by_mip[static_cast<std::size_t>(m)];
  }
  return c;
}

}  // namespace vtsim
