#include "stream/system/clipmap_system.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <fmt/format.h>

#include "core/error.h"

namespace vtsim {

ClipmapSystem::ClipmapSystem(const SystemSetup& s, const ClipmapConfig& c) : ClipmapBacked(params(s, c)), s_(s) {}

ClipmapParams ClipmapSystem::params(const SystemSetup& s, const ClipmapConfig& c) {
  ClipmapParams p;
  static_cast<ClipmapConfig&>(p) = c;
  p.extent = s.extent;
  p.tile_size = s.tile_size;
  p.layers = s.layers;
  return p;
}

namespace {

// Largest clip window side in tiles: 256² tiles a level is already far beyond any engine's window
// (RAGE-style clipmaps keep 8-32 tiles a side), and a frame tracks every tile of every window.
constexpr int kMaxClipTiles = 256;

[[noreturn]] void bad_clipmap_field(const std::string& key, const std::string& what) {
  throw InputError("config", "field '" + key + "': " + what);
}

}  // namespace

void ClipmapSystem::validate(const SystemSetup& s, const ClipmapConfig& c, const ThrottleParams&) {
  if (c.clipsize % s.tile_size != 0)
    bad_clipmap_field("clipmap.clipsize", fmt::format("{} is not a multiple of texture.tile_size {}", c.clipsize, s.tile_size));
  // A window is (clipsize / tile)² tiles per level, all tracked every frame.
  if (c.clipsize / s.tile_size > kMaxClipTiles)
    bad_clipmap_field("clipmap.clipsize", fmt::format("{} is more than {} tiles of {} texels a side: use larger tiles",
                                                      c.clipsize, kMaxClipTiles, s.tile_size));
  if (s.border != 0)
    bad_clipmap_field("texture.border", "the clipmap's toroidal windows keep neighbours adjacent: borders must be 0");
}

int ClipmapSystem::store_levels(const SystemSetup& s, const ClipmapConfig&) { return mip_level_count(s.extent); }

VramArena ClipmapSystem::vram_arena(const SystemSetup& s, const ClipmapConfig& c, std::vector<std::uint32_t> layer_bytes,
                                    std::uint64_t host_limit) {
  return VramArena::for_clipmap(params(s, c), std::move(layer_bytes), host_limit);
}

std::int64_t ClipmapSystem::ground_u(double x_m) const {
  return static_cast<std::int64_t>(std::floor((x_m - s_.origin_x_m) * s_.texels_per_m));
}
std::int64_t ClipmapSystem::ground_v(double y_m) const {
  return static_cast<std::int64_t>(std::floor((y_m - s_.origin_y_m) * s_.texels_per_m));
}

void ClipmapSystem::begin_frame(const SystemFrame& f) {
  frame_ = f.frame;
  gu_ = ground_u(f.pose->pos_m.x);
  gv_ = ground_v(f.pose->pos_m.y);
  finest_active_ = std::min(f.finest_needed, cm_.num_levels());
  spans_ = f.spans;
  view_ = f.view;
  uses_ready_ = false;
  prefetch_ = s_.prefetch_lookahead_s > 0 && (f.velocity_mps.x != 0.0 || f.velocity_mps.y != 0.0);
  if (prefetch_) {
    fu_ = ground_u(f.pose->pos_m.x + f.velocity_mps.x * s_.prefetch_lookahead_s);
    fv_ = ground_v(f.pose->pos_m.y + f.velocity_mps.y * s_.prefetch_lookahead_s);
  }
}

void ClipmapSystem::missing_bytes_by_level(std::vector<std::uint64_t>& out) const {
  cm_.missing_bytes_by_level(gu_, gv_, finest_active_, s_.tile_bytes_all_layers, out);
}

std::uint64_t ClipmapSystem::importance(int level, std::int64_t x, std::int64_t y) {
  if (!uses_ready_) {  // the frame's feedback, aggregated once when first asked (uses_)
    if (spans_) aggregate_feedback(*spans_, s_.tile_size, cm_.num_levels(), uses_);
    else if (view_) aggregate_feedback(*view_, s_.tile_size, cm_.num_levels(), uses_);
    else uses_.clear();
    uses_ready_ = true;
  }
  const TileKey k(0, static_cast<std::uint32_t>(level), x, y);
  auto it = std::lower_bound(uses_.begin(), uses_.end(), k, [](const TileUse& a, TileKey b) { return a.key < b; });
  return it != uses_.end() && it->key == k ? it->samples : 0;
}

void ClipmapSystem::emit_needs(std::vector<Need>& out) {
  // Windows move only for levels that are sampled (not finer than the clamp or than any sample).
  cm_.update_windows(gu_, gv_, finest_active_);
  const std::size_t before = out.size();
  cm_.emit_needs(finest_active_, [this](int l, std::int64_t x, std::int64_t y) { return importance(l, x, y); }, out);
  throttled_ = 0;
  if (cm_.clamp() > finest_active_) {
    std::vector<std::uint64_t> missing;
    cm_.missing_bytes_by_level(gu_, gv_, finest_active_, s_.tile_bytes_all_layers, missing);
    const std::uint64_t per_tile = std::max<std::uint64_t>(1, s_.tile_bytes_all_layers / static_cast<std::uint64_t>(s_.layers));
    for (int l = finest_active_; l < cm_.clamp() && l < cm_.num_levels(); ++l)
      throttled_ += static_cast<std::uint32_t>(missing[static_cast<std::size_t>(l)] / per_tile);
  }
  (void)before;
  if (prefetch_) cm_.emit_prefetch(fu_, fv_, finest_active_, out);
}

bool ClipmapSystem::commit(TileKey key, int frame) {
  Clipmap::Evicted ev;
  if (!cm_.commit(key, &ev)) return false;
  const auto pack = [](std::uint32_t l, std::int64_t x, std::int64_t y) {
    return TileKey(0, l, x, y).bits;
  };
  if (ev.mask) evicted_at_[pack(key.level(), ev.tx, ev.ty)] = frame;
  if (key.layer() == 0 && !evicted_at_.empty()) {
    auto it = evicted_at_.find(pack(key.level(), key.x(), key.y()));
    if (it != evicted_at_.end()) {
      if (frame - it->second <= s_.thrash_frames) ++thrash_;
      evicted_at_.erase(it);
    }
  }
  if (evicted_at_.size() > 65536) {  // forget evictions too old to count as thrash
    for (auto it = evicted_at_.begin(); it != evicted_at_.end();)
      it = frame - it->second > s_.thrash_frames ? evicted_at_.erase(it) : std::next(it);
  }
  return true;
}

std::uint64_t ClipmapSystem::evicted_unsampled_bytes() const {
  return cm_.stats().evicted_unsampled * (s_.tile_bytes_all_layers / static_cast<std::uint64_t>(s_.layers));
}

nlohmann::json ClipmapSystem::stats_json() const {
  const auto& s = cm_.stats();
  return {{"levels", cm_.num_levels()},
          {"stack_levels", cm_.first_pyramid_level()},
          {"window_tiles", cm_.window_tiles()},
          {"window_moves", s.window_moves},
          {"vram_evictions", s.vram_evictions},
          {"stale_commits", s.stale_commits},
          {"resident_unsampled_tiles", cm_.resident_unsampled()}};
}

}  // namespace vtsim
