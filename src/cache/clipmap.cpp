#include "cache/clipmap.h"

#include <algorithm>
#include <bit>
#include <climits>
#include <cmath>
#include <stdexcept>

namespace vtsim {

namespace {

// Floor division and modulo for signed coordinates (camera outside the texture, negative tiles).
inline std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  const std::int64_t q = a / b;
  return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}
inline std::int64_t floor_mod(std::int64_t a, std::int64_t b) { return a - floor_div(a, b) * b; }
inline std::int64_t ceil_div(std::int64_t a, std::int64_t b) { return (a + b - 1) / b; }

// Fingerprint lanes (IResidency::fingerprint): values chained through a SplitMix64 step (Steele,
// Lea & Flood 2014: the golden-ratio increment, then mix64's finaliser), one seed per lane.
constexpr std::uint64_t kFpSeed[2] = {0x6a09e667f3bcc908ULL, 0xbb67ae8584caa73bULL};
inline std::uint64_t fp_chain(std::uint64_t h, std::uint64_t v) { return mix64((h ^ v) + 0x9e3779b97f4a7c15ULL); }
inline std::uint64_t fp_bits(std::int64_t v) { return static_cast<std::uint64_t>(v); }

}  // namespace

ClipmapMemory clipmap_memory(TextureExtent e, int tile_size, int clipsize) {
  ClipmapMemory m;
  const std::int64_t n = clipsize / tile_size;
  std::int64_t w = e.width, h = e.height;
  for (;;) {
    ++m.levels;
    const auto area = static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h);
    m.full_mip_texels += area;
    if (std::max(w, h) > clipsize) {
      ++m.stack_levels;
      const std::int64_t wx = std::min(n, ceil_div(w, tile_size)), wy = std::min(n, ceil_div(h, tile_size));
      m.stack_texels += static_cast<std::uint64_t>(wx * tile_size) * static_cast<std::uint64_t>(wy * tile_size);
    } else {
      ++m.pyramid_levels;
      m.pyramid_texels += area;
    }
    if (w == 1 && h == 1) break;
    w = (w + 1) / 2;
    h = (h + 1) / 2;
  }
  return m;
}

Clipmap::Clipmap(const ClipmapParams& p) : p_(p) {
  if (p.extent.width <= 0 || p.extent.height <= 0) throw std::invalid_argument("clipmap: empty texture");
  if (p.tile_size <= 0 || p.clipsize <= 0 || p.clipsize % p.tile_size != 0)
    throw std::invalid_argument("clipmap: clipsize must be a positive multiple of the tile size");
  if (p.layers < 1 || p.layers > 16) throw std::invalid_argument("clipmap: layers must be 1..16");
  n_ = p.clipsize / p.tile_size;
  if ((p.tile_size & (p.tile_size - 1)) == 0) tile_shift_ = std::countr_zero(static_cast<unsigned>(p.tile_size));
  full_mask_ = p.layers == 32 ? 0xFFFFFFFFu : (1u << p.layers) - 1u;
  std::int64_t w = p.extent.width, h = p.extent.height;
  first_pyramid_ = -1;
  for (int l = 0;; ++l) {
    Level L;
    L.texels_x = w;
    L.texels_y = h;
    L.tiles_x = ceil_div(w, p.tile_size);
    L.tiles_y = ceil_div(h, p.tile_size);
    L.stack = std::max(w, h) > p.clipsize;
    if (L.stack) {
      L.wx = std::min<std::int64_t>(n_, L.tiles_x);
      L.wy = std::min<std::int64_t>(n_, L.tiles_y);
    } else {
      if (first_pyramid_ < 0) first_pyramid_ = l;
      L.wx = L.tiles_x;
      L.wy = L.tiles_y;
      L.placed = true;  // the pyramid's window is the whole level
      L.cx = L.tiles_x / 2;
      L.cy = L.tiles_y / 2;
    }
    L.slots.resize(static_cast<std::size_t>(L.wx * L.wy));
    if (!L.stack) set_window(L, 0, 0);
    L.missing = static_cast<std::uint64_t>(L.wx * L.wy) * static_cast<std::uint64_t>(p.layers);
    levels_.push_back(std::move(L));
    if (w == 1 && h == 1) break;
    w = (w + 1) / 2;
    h = (h + 1) / 2;
  }
  if (levels_.size() > TileKey::kMaxLevels) throw std::invalid_argument("clipmap: too many levels");
  for (int k = 0; k < 2; ++k) {
    std::uint64_t fp = kFpSeed[k];
    for (const std::int64_t v : {p.extent.width, p.extent.height, std::int64_t{p.tile_size}, std::int64_t{p.layers},
                                 std::int64_t{p.clipsize}, std::int64_t{p.invalid_border_tiles}, std::int64_t{p.filter_margin_texels},
                                 std::bit_cast<std::int64_t>(p.update_threshold_tiles)})
      fp = fp_chain(fp, fp_bits(v));
    param_fp_[k] = fp;
    for (std::size_t l = 0; l < levels_.size(); ++l) window_fp_[k] ^= window_term(kFpSeed[k], static_cast<int>(l), levels_[l]);
  }
}

std::uint64_t Clipmap::window_term(std::uint64_t seed, int level, const Level& L) {
  if (!L.placed) return 0;
  return fp_chain(fp_chain(fp_chain(seed, static_cast<std::uint64_t>(level) | std::uint64_t{1} << 32), fp_bits(L.ox)), fp_bits(L.oy));
}

std::uint64_t Clipmap::slot_term(std::uint64_t seed, int level, std::size_t slot, const Slot& s) {
  if (s.mask == 0) return 0;
  std::uint64_t h = fp_chain(seed, static_cast<std::uint64_t>(level) << 40 | slot);
  h = fp_chain(h, fp_bits(s.tx));
  h = fp_chain(h, fp_bits(s.ty));
  return fp_chain(h, s.mask);
}

bool Clipmap::fingerprint(ResidencyFingerprint& out) const {
  std::uint64_t h[2];
  for (int k = 0; k < 2; ++k)
    h[k] = fp_chain(fp_chain(fp_chain(param_fp_[k], slot_fp_[k]), window_fp_[k]), static_cast<std::uint64_t>(clamp_));
  out = {h[0], h[1]};
  return true;
}

void Clipmap::record_marks(std::vector<std::uint64_t>* out) const {
  marks_ = out;
  if (!out) return;
  if (++mark_epoch_ == 0) {  // the epochs wrapped: forget every slot's
    for (const Level& L : levels_)
      for (const Slot& sl : L.slots) sl.marked = 0;
    mark_epoch_ = 1;
  }
}

void Clipmap::apply_marks(const std::vector<std::uint64_t>& marks) const {
  for (const std::uint64_t m : marks) {
    const std::size_t l = static_cast<std::size_t>(m >> 40), slot = static_cast<std::size_t>(m & ((std::uint64_t{1} << 40) - 1));
    if (l >= levels_.size() || slot >= levels_[l].slots.size()) throw std::invalid_argument("clipmap: apply_marks: no such slot");
    mark(levels_[l], static_cast<int>(l), slot);
  }
}

std::size_t Clipmap::slot_index(const Level& L, std::int64_t tx, std::int64_t ty) const {
  return static_cast<std::size_t>(floor_mod(ty, L.wy) * L.wx + floor_mod(tx, L.wx));
}

bool Clipmap::in_window(const Level& L, std::int64_t tx, std::int64_t ty) const {
  return L.placed && tx >= L.ox && tx < L.ox + L.wx && ty >= L.oy && ty < L.oy + L.wy;
}

void Clipmap::set_window(Level& L, std::int64_t ox, std::int64_t oy) {
  L.ox = ox;
  L.oy = oy;
  L.sx0 = floor_mod(ox, L.wx);
  L.sy0 = floor_mod(oy, L.wy);
  const std::int64_t T = p_.tile_size, b = L.stack ? p_.invalid_border_tiles : 0;
  // The invalid border (Yao 2007 §4-6) lies along window edges that can move; an edge on the
  // texture's edge never receives new tiles.
  const std::int64_t tx0 = ox + (ox > 0 ? b : 0), tx1 = ox + L.wx - (ox + L.wx < L.tiles_x ? b : 0);
  const std::int64_t ty0 = oy + (oy > 0 ? b : 0), ty1 = oy + L.wy - (oy + L.wy < L.tiles_y ? b : 0);
  L.vx0 = tx0 * T;
  L.vx1 = std::min(L.texels_x, tx1 * T);
  L.vy0 = ty0 * T;
  L.vy1 = std::min(L.texels_y, ty1 * T);
}

Clipmap::Window Clipmap::window(int level) const {
  const Level& L = levels_.at(static_cast<std::size_t>(level));
  return {L.ox, L.oy, L.wx, L.wy};
}

void Clipmap::target_window(const Level& L, int level, std::int64_t gu, std::int64_t gv, std::int64_t& cx,
                            std::int64_t& cy, std::int64_t& ox, std::int64_t& oy, bool& moved) const {
  const std::int64_t T = p_.tile_size;
  const std::int64_t gl_x = gu >> level, gl_y = gv >> level;  // arithmetic shift: floor for negatives
  const std::int64_t thr = static_cast<std::int64_t>(std::llround(p_.update_threshold_tiles * static_cast<double>(T)));
  cx = L.cx;
  cy = L.cy;
  moved = false;
  auto axis = [&](std::int64_t g, std::int64_t& c) {
    const std::int64_t d = g - (c * T + T / 2);
    if (!L.placed || d >= T - T / 2 + thr || d < -(T / 2) - thr) {
      const std::int64_t nc = floor_div(g, T);
      if (nc != c || !L.placed) moved = true;
      c = nc;
    }
  };
  axis(gl_x, cx);
  axis(gl_y, cy);
  ox = std::clamp<std::int64_t>(cx - n_ / 2, 0, std::max<std::int64_t>(0, L.tiles_x - L.wx));
  oy = std::clamp<std::int64_t>(cy - n_ / 2, 0, std::max<std::int64_t>(0, L.tiles_y - L.wy));
}

void Clipmap::recount(Level& L) {
  L.missing = missing_in(L, L.ox, L.oy);
}

std::uint64_t Clipmap::missing_in(const Level& L, std::int64_t ox, std::int64_t oy) const {
  std::uint64_t missing = 0;
  for (std::int64_t ty = oy; ty < oy + L.wy; ++ty)
    for (std::int64_t tx = ox; tx < ox + L.wx; ++tx) {
      const Slot& s = L.slots[slot_index(L, tx, ty)];
      const std::uint32_t have = (s.tx == tx && s.ty == ty) ? s.mask : 0u;
      missing += static_cast<std::uint64_t>(p_.layers - std::popcount(have));
    }
  return missing;
}

int Clipmap::update_windows(std::int64_t gu, std::int64_t gv, int finest_active) {
  const int from = std::max(finest_active, clamp_);
  int moved_levels = 0;
  for (int l = std::max(from, 0); l < num_levels(); ++l) {
    Level& L = levels_[static_cast<std::size_t>(l)];
    if (!L.stack) break;  // pyramid levels follow the stack and never move
    std::int64_t cx, cy, ox, oy;
    bool moved;
    target_window(L, l, gu, gv, cx, cy, ox, oy, moved);
    L.cx = cx;
    L.cy = cy;
    if (!L.placed || ox != L.ox || oy != L.oy) {
      for (int k = 0; k < 2; ++k) window_fp_[k] ^= window_term(kFpSeed[k], l, L);
      set_window(L, ox, oy);
      L.placed = true;
      for (int k = 0; k < 2; ++k) window_fp_[k] ^= window_term(kFpSeed[k], l, L);
      recount(L);
      fast_dirty_ = true;
      ++stats_.window_moves;
      ++moved_levels;
    }
  }
  return moved_levels;
}

void Clipmap::missing_bytes_by_level(std::int64_t gu, std::int64_t gv, int finest_active,
                                     std::uint64_t tile_bytes_all_layers, std::vector<std::uint64_t>& out) const {
  out.assign(levels_.size(), 0);
  const std::uint64_t per_layer = tile_bytes_all_layers / static_cast<std::uint64_t>(p_.layers);
  for (int l = 0; l < num_levels(); ++l) {
    const Level& L = levels_[static_cast<std::size_t>(l)];
    if (L.stack && l < finest_active) continue;
    std::uint64_t missing = L.missing;
    if (L.stack) {
      std::int64_t cx, cy, ox, oy;
      bool moved;
      target_window(L, l, gu, gv, cx, cy, ox, oy, moved);
      if (!L.placed || ox != L.ox || oy != L.oy) missing = missing_in(L, ox, oy);
    }
    out[static_cast<std::size_t>(l)] = missing * per_layer;
  }
}

void Clipmap::emit_prefetch(std::int64_t fu, std::int64_t fv, int finest_active, std::vector<Need>& out) const {
  const int from = std::max(finest_active, clamp_);
  for (int l = std::max(from, 0); l < num_levels(); ++l) {
    const Level& L = levels_[static_cast<std::size_t>(l)];
    if (!L.stack) break;
    if (!L.placed) continue;
    std::int64_t cx, cy, ox, oy;
    bool moved;
    target_window(L, l, fu, fv, cx, cy, ox, oy, moved);
    if (ox == L.ox && oy == L.oy) continue;
    for (std::int64_t ty = oy; ty < oy + L.wy; ++ty)
      for (std::int64_t tx = ox; tx < ox + L.wx; ++tx) {
        if (in_window(L, tx, ty)) continue;  // already wanted (or resident) as a demand tile
        const std::int64_t dx = tx - L.cx, dy = ty - L.cy;
        const auto dist = static_cast<std::uint32_t>((dx < 0 ? -dx : dx) + (dy < 0 ? -dy : dy));
        const std::uint64_t prio = make_priority(static_cast<std::uint32_t>(l), 0, dist);
        for (int layer = 0; layer < p_.layers; ++layer)
          out.push_back(Need{TileKey(static_cast<std::uint32_t>(layer), static_cast<std::uint32_t>(l), tx, ty), prio, true});
      }
  }
}

bool Clipmap::accepts(TileKey key) const {
  const int l = static_cast<int>(key.level());
  if (l >= num_levels() || static_cast<int>(key.layer()) >= p_.layers) return false;
  return in_window(levels_[static_cast<std::size_t>(l)], key.x(), key.y());
}

bool Clipmap::commit(TileKey key, Evicted* evicted) {
  const int l = static_cast<int>(key.level());
  if (l >= num_levels() || static_cast<int>(key.layer()) >= p_.layers) return false;
  Level& L = levels_[static_cast<std::size_t>(l)];
  const std::int64_t tx = key.x(), ty = key.y();
  if (!in_window(L, tx, ty)) {
    ++stats_.stale_commits;
    return false;
  }
  const std::size_t slot = slot_index(L, tx, ty);
  Slot& s = L.slots[slot];
  for (int k = 0; k < 2; ++k) slot_fp_[k] ^= slot_term(kFpSeed[k], l, slot, s);
  if (s.tx != tx || s.ty != ty) {
    if (s.mask) {
      if (evicted) *evicted = Evicted{s.tx, s.ty, s.mask, s.sampled};
      const auto n = static_cast<std::uint64_t>(std::popcount(s.mask));
      stats_.vram_evictions += n;
      if (!s.sampled) stats_.evicted_unsampled += n;
    }
    s.tx = tx;
    s.ty = ty;
    s.mask = 0;
    s.sampled = false;
  }
  const std::uint32_t bit = 1u << key.layer();
  if (!(s.mask & bit)) {
    s.mask |= bit;
    if (--L.missing == 0) fast_dirty_ = true;
  }
  for (int k = 0; k < 2; ++k) slot_fp_[k] ^= slot_term(kFpSeed[k], l, slot, s);
  return true;
}

int Clipmap::sampled(TileKey key) const {
  if (!resident(key)) return -1;
  const Level& L = levels_[key.level()];
  return L.slots[slot_index(L, key.x(), key.y())].sampled ? 1 : 0;
}

bool Clipmap::resident(TileKey key) const {
  const int l = static_cast<int>(key.level());
  if (l >= num_levels()) return false;
  const Level& L = levels_[static_cast<std::size_t>(l)];
  if (!in_window(L, key.x(), key.y())) return false;
  const Slot& s = L.slots[slot_index(L, key.x(), key.y())];
  return s.tx == key.x() && s.ty == key.y() && (s.mask & (1u << key.layer()));
}

int Clipmap::resident_level(std::int64_t u, std::int64_t v, int desired_level) const {
  const std::int64_t m = p_.filter_margin_texels;
  for (int l = std::max(desired_level, clamp_); l < num_levels(); ++l) {
    const Level& L = levels_[static_cast<std::size_t>(l)];
    if (!L.placed) continue;
    const std::int64_t ul = u >> l, vl = v >> l;
    // The footprint, clamped at the texture's edges (clamp addressing), must lie in the valid
    // rectangle; a complete level needs nothing more, others need every footprint tile resident.
    const std::int64_t x0 = std::max<std::int64_t>(0, ul - m), x1 = std::min(L.texels_x - 1, ul + m);
    const std::int64_t y0 = std::max<std::int64_t>(0, vl - m), y1 = std::min(L.texels_y - 1, vl + m);
    if (x0 < L.vx0 || x1 >= L.vx1 || y0 < L.vy0 || y1 >= L.vy1) continue;
    if (L.missing != 0) {
      const std::int64_t tx0 = tile_of(x0), tx1 = tile_of(x1), ty0 = tile_of(y0), ty1 = tile_of(y1);
      bool ok = true;
      for (std::int64_t ty = ty0; ok && ty <= ty1; ++ty)
        for (std::int64_t tx = tx0; ok && tx <= tx1; ++tx) {
          const Slot& s = L.slots[window_slot(L, tx, ty)];
          ok = s.tx == tx && s.ty == ty && s.mask == full_mask_;
        }
      if (!ok) continue;
    }
    if (mark_sampled_) mark(L, l, window_slot(L, tile_of(ul), tile_of(vl)));
    return l;
  }
  return num_levels();
}

void Clipmap::rebuild_fast() const {
  fast_.resize(levels_.size());
  const std::int64_t m = p_.filter_margin_texels;
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    const Level& L = levels_[l];
    FastRect& f = fast_[l];
    if (!L.placed || L.missing != 0) {
      f = {0, 0, 0, 0};
      continue;
    }
    // A centre texel c passes when clamp(c - m, 0) >= vx0 and clamp(c + m, W - 1) < vx1; at a
    // texture edge the clamp makes the margin vanish, so the rectangle reaches the edge.
    f.x0 = L.vx0 == 0 ? 0 : L.vx0 + m;
    f.x1 = L.vx1 == L.texels_x ? L.texels_x : L.vx1 - m;
    f.y0 = L.vy0 == 0 ? 0 : L.vy0 + m;
    f.y1 = L.vy1 == L.texels_y ? L.texels_y : L.vy1 - m;
  }
  fast_dirty_ = false;
}

void Clipmap::resident_levels(const ViewSample* s, std::size_t n, std::int8_t* out) const {
  if (fast_dirty_) rebuild_fast();
  const int levels = num_levels();
  const int clamp = clamp_;
  const FastRect* fr = fast_.data();
  // Marking sampled slots: consecutive samples mostly resolve to the same tile; skip repeats.
  int last_l = -1;
  std::int64_t last_tx = -1, last_ty = -1;
  for (std::size_t i = 0; i < n; ++i) {
    const int d = desired_level(s[i].lod, levels);
    const int l0 = d > clamp ? d : clamp;
    int r;
    if (l0 < levels) {
      const FastRect& f = fr[l0];
      const std::int64_t ul = s[i].u >> l0, vl = s[i].v >> l0;
      if (ul >= f.x0 && ul < f.x1 && vl >= f.y0 && vl < f.y1) {
        r = l0;
        if (mark_sampled_) {
          const std::int64_t tx = tile_of(ul), ty = tile_of(vl);
          if (r != last_l || tx != last_tx || ty != last_ty) {
            const Level& L = levels_[static_cast<std::size_t>(r)];
            mark(L, r, window_slot(L, tx, ty));
            last_l = r, last_tx = tx, last_ty = ty;
          }
        }
        out[i] = static_cast<std::int8_t>(r);
        continue;
      }
    }
    out[i] = static_cast<std::int8_t>(resident_level(s[i].u, s[i].v, d));
  }
}

void Clipmap::span_resident_levels(const ViewSpan* s, std::size_t n, std::int8_t* out) const {
  const int levels = num_levels();
  const std::int64_t m = p_.filter_margin_texels;
  // Per level, once per call: resident_level's rectangle test on one axis, max(0, c − m) >= lo &&
  // min(W − 1, c + m) < hi, holds exactly for centres c in [A, B]; unplaced levels never pass.
  struct Rect {
    std::int64_t Au, Bu, Av, Bv;
  };
  Rect rect[TileKey::kMaxLevels];
  for (int l = 0; l < levels; ++l) {
    const Level& L = levels_[static_cast<std::size_t>(l)];
    Rect& R = rect[l];
    if (!L.placed) {
      R = {INT64_MAX, INT64_MIN, INT64_MAX, INT64_MIN};
      continue;
    }
    R.Au = L.vx0 <= 0 ? INT64_MIN : L.vx0 + m;
    R.Bu = L.texels_x - 1 < L.vx1 ? INT64_MAX : L.vx1 - m - 1;
    R.Av = L.vy0 <= 0 ? INT64_MIN : L.vy0 + m;
    R.Bv = L.texels_y - 1 < L.vy1 ? INT64_MAX : L.vy1 - m - 1;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const ViewSpan& sp = s[i];
    const int d = sp.level < levels - 1 ? sp.level : levels - 1;
    int r = levels;  // nothing resident for any sample, unless a level below says otherwise
    for (int l = std::max(d, clamp_); l < levels; ++l) {
      const Rect& R = rect[l];
      // The span's centres lie in [a, b] × [c, e].
      const std::int64_t a = sp.u_lo >> l, b = sp.u_hi >> l, c = sp.v_lo >> l, e = sp.v_hi >> l;
      if (b < R.Au || a > R.Bu || e < R.Av || c > R.Bv) continue;  // no sample passes (or unplaced)
      if (a < R.Au || b > R.Bu || c < R.Av || e > R.Bv) {          // some may pass, some not
        r = -1;
        break;
      }
      const Level& L = levels_[static_cast<std::size_t>(l)];
      if (L.missing != 0) {
        // Every sample's footprint tiles lie among the box footprint's tiles and include the
        // sample's own tile: all resident → all pass, none resident → none pass.
        const std::int64_t tx0 = tile_of(std::max<std::int64_t>(0, a - m)), tx1 = tile_of(std::min(L.texels_x - 1, b + m));
        const std::int64_t ty0 = tile_of(std::max<std::int64_t>(0, c - m)), ty1 = tile_of(std::min(L.texels_y - 1, e + m));
        if ((tx1 - tx0 + 1) * (ty1 - ty0 + 1) > 16) {
          r = -1;
          break;
        }
        int have = 0, total = 0;
        for (std::int64_t ty = ty0; ty <= ty1; ++ty)
          for (std::int64_t tx = tx0; tx <= tx1; ++tx) {
            const Slot& sl = L.slots[window_slot(L, tx, ty)];
            have += sl.tx == tx && sl.ty == ty && sl.mask == full_mask_;
            ++total;
          }
        if (have == 0) continue;
        if (have != total) {
          r = -1;
          break;
        }
      }
      r = l;
      if (mark_sampled_) {  // resident_level marks each sample's tile at the level it resolves to
        if (tile_of(a) != tile_of(b) || tile_of(c) != tile_of(e)) {
          r = -1;
          break;
        }
        mark(L, l, window_slot(L, tile_of(a), tile_of(c)));
      }
      break;
    }
    out[i] = static_cast<std::int8_t>(r);
  }
}

std::uint64_t Clipmap::resident_unsampled() const {
  std::uint64_t n = 0;
  for (const Level& L : levels_)
    for (const Slot& s : L.slots)
      if (s.mask && !s.sampled) n += static_cast<std::uint64_t>(std::popcount(s.mask));
  return n;
}

}  // namespace vtsim
