#pragma once
// The clipmap's VRAM: a clip stack of N×N windows (whole tiles) over a static clip pyramid
// (Tanner, Migdal & Jones, "The Clipmap: A Virtual Mipmap", SIGGRAPH 1998; Yao 2007 §2-2, §3-2,
// §4-6, §4-7). docs/clipmap.md.
//
// Geometry. Level l of a W×H texture is ceil(W/2^l) × ceil(H/2^l) texels, cut into T×T tiles.
// Levels whose larger side exceeds the clipsize N are the *stack*: each keeps a window of
// n = N/T tiles a side (fewer along a side shorter than N) centred on the camera's ground point;
// the rest are the *pyramid*, whose window is the whole level: loaded once, never moved.
//
// Toroidal addressing (Yao 2007 §3-2). Tile (x, y) of a level lives in slot (x mod wx, y mod wy):
// when a window moves, only tiles that entered need loading; each overwrites the slot of a tile
// that left. A slot remembers which tile it holds and which layers of it are resident.
//
// Hysteresis. A stack window recentres on an axis only when the camera's ground texel is more
// than T/2 + threshold·T texels from the centre of the window's centre tile (Unity Clipmap's
// UpdateThreshold), so a camera dithering across a tile edge does not ping-pong.
//
// World edges (Yao 2007 §4-7). A window is clamped inside its level: near an edge the camera is
// off-centre but all N×N texels are real texture (no dummy blocks, unlike Unity Clipmap). A camera
// outside the texture pulls the windows to the nearest edge.
//
// Level selection (the fix for Unity Clipmap's shader, which counted containing layers): a sample at
// level-0 texel (u, v) with desired level d uses the finest level l >= max(d, clamp) whose valid
// region contains its filter footprint: every texel within `filter_margin` of (u>>l, v>>l) lies in
// a tile that is in the window, outside the invalid border, and resident in all layers. So a finer
// level that commits before a coarser one is used where it is valid, and nothing is sampled from a
// tile being rewritten.
//
// Complexity: resident_level O(levels tried) with 1–4 slot probes each; update_windows O(n² ×
// layers) per moved level; emit_needs O(n² × layers) per incomplete level, nothing for complete
// ones. Memory: one 24-byte slot per window tile per level. Single-threaded.
#include <cstdint>
#include <vector>

#include "cache/i_residency.h"
#include "cache/need.h"
#include "core/tile_key.h"
#include "core/view.h"

namespace vtsim {

// How the windows behave: the config's [clipmap] section.
struct ClipmapConfig {
  int clipsize = 1024;                    // N: window side in texels, a multiple of T
  double update_threshold_tiles = 0.5;    // hysteresis beyond the centre tile, in tiles (>= 0)
  int invalid_border_tiles = 0;           // window tiles at each moving edge excluded from sampling
  int filter_margin_texels = 1;           // footprint half-width that must be valid (bilinear: 1)
};

struct ClipmapParams : ClipmapConfig {
  TextureExtent extent{1 << 20, 1 << 20};  // level-0 texels
  int tile_size = 128;                    // T: payload texels per tile side
  int layers = 1;                         // layers streamed per tile (albedo, normal, ...)
};

// VRAM bytes of a clipmap (Yao 2007 §2-3): the stack's windows and the pyramid's full levels.
struct ClipmapMemory {
  int levels = 0, stack_levels = 0, pyramid_levels = 0;
  std::uint64_t stack_texels = 0;    // sum of window areas (whole tiles), all stack levels
  std::uint64_t pyramid_texels = 0;  // sum of the pyramid's level areas
  std::uint64_t full_mip_texels = 0; // sum of every level's area: a full mip chain
};
ClipmapMemory clipmap_memory(TextureExtent extent, int tile_size, int clipsize);

class Clipmap final : public IResidency {
 public:
  explicit Clipmap(const ClipmapParams& p);

  int num_levels() const override { return static_cast<int>(levels_.size()); }
  int first_pyramid_level() const { return first_pyramid_; }
  int window_tiles() const { return n_; }
  const ClipmapParams& params() const { return p_; }

  // MaxTextureLOD (Yao 2007 §4-4): the finest level sampled and requested, 0 = none.
  void set_clamp(int clamp) { clamp_ = clamp; }
  int clamp() const { return clamp_; }

  // Moves the windows of stack levels >= max(finest_active, clamp) toward the camera's ground
  // texel (level-0 coordinates; may lie outside the texture). Levels finer than `finest_active`
  // (no visible sample wants them) and finer than the clamp keep their windows (Yao 2007: do not
  // update what is not sampled). Returns the number of levels whose window moved.
  int update_windows(std::int64_t gu, std::int64_t gv, int finest_active);

  // Bytes (all layers) each level still misses to be complete, as if levels >= finest_active were
  // updated now, regardless of the clamp: what a throttling policy weighs.
  void missing_bytes_by_level(std::int64_t gu, std::int64_t gv, int finest_active,
                              std::uint64_t tile_bytes_all_layers, std::vector<std::uint64_t>& out) const;

  // Appends every non-resident (tile, layer) of the windows of levels >= max(finest_active, clamp),
  // pyramid included. `importance(level, x, y)` is the tile's screen importance (e.g. samples).
  template <class Importance>
  void emit_needs(int finest_active, Importance&& importance, std::vector<Need>& out) const;

  // Look-ahead (Yao 2007 §4-2): tiles that the windows of active levels will enter if the ground
  // point moves to (fu, fv), not resident now — to fetch into RAM ahead of need.
  void emit_prefetch(std::int64_t fu, std::int64_t fv, int finest_active, std::vector<Need>& out) const;

  // A tile layer finished uploading. Returns false (and changes nothing) if the tile is no longer
  // in its level's window. Overwriting a slot that held another tile is a VRAM eviction.
  struct Evicted {
    std::int64_t tx = -1, ty = -1;  // tile whose slot was overwritten
    std::uint32_t mask = 0;         // its layers that were resident (0: nothing evicted)
    bool sampled = false;
  };
  bool commit(TileKey key, Evicted* evicted = nullptr);
  // What commit(key) would answer now, without its effects.
  bool accepts(TileKey key) const;

  bool resident(TileKey key) const;  // that layer of that tile is in VRAM and in its window
  // -1: that layer of that tile is not resident (resident()); 0: resident and no sample resolved
  // to its slot yet; 1: a sample has (set_mark_sampled). O(1).
  int sampled(TileKey key) const;
  bool level_complete(int level) const { return levels_[static_cast<std::size_t>(level)].missing == 0; }
  bool window_placed(int level) const { return levels_[static_cast<std::size_t>(level)].placed; }
  // Window origin and size in tiles of a level.
  struct Window {
    std::int64_t x0, y0, w, h;
  };
  Window window(int level) const;

  int resident_level(std::int64_t u, std::int64_t v, int desired_level) const override;
  // Fast path: a sample whose footprint lies in a complete level's valid rectangle resolves with a
  // few compares; everything else goes through resident_level.
  void resident_levels(const ViewSample* s, std::size_t n, std::int8_t* out) const override;
  // Per span, O(levels tried) with a few slot probes: the footprints of a span's samples lie in
  // the footprint of its bounding box, and each validity test (inside the valid rectangle, tiles
  // resident) holds for all samples when it holds for that box, and for none when the box misses
  // the rectangle or every tile under it is missing; otherwise −1 (the caller goes per sample).
  void span_resident_levels(const ViewSpan* s, std::size_t n, std::int8_t* out) const override;
  // When on, resident_level marks the slot it resolves to as sampled (for wasted-upload metrics).
  void set_mark_sampled(bool on) { mark_sampled_ = on; }
  // IResidency's sharing: the parameters, each level's window, the clamp and every slot's tile
  // and layers (not the sampled flags, which no lookup reads), O(1): commit keeps the slots'
  // part and update_windows the windows'. A mark is (level << 40 | slot).
  bool fingerprint(ResidencyFingerprint& out) const override;
  void record_marks(std::vector<std::uint64_t>* out) const override;
  void apply_marks(const std::vector<std::uint64_t>& marks) const override;

  struct Stats {
    std::uint64_t window_moves = 0;       // level recentres
    std::uint64_t vram_evictions = 0;     // resident tile layers overwritten by another tile
    std::uint64_t evicted_unsampled = 0;  // of those, never sampled while resident
    std::uint64_t stale_commits = 0;      // uploads that arrived for a tile no longer in its window
  };
  const Stats& stats() const { return stats_; }
  // Tile layers resident now that were never sampled.
  std::uint64_t resident_unsampled() const;

 private:
  struct Slot {
    std::int64_t tx = -1, ty = -1;  // tile held (level coordinates), -1 = none
    std::uint32_t mask = 0;         // resident layers of that tile
    mutable bool sampled = false;
    mutable std::uint8_t marked = 0;  // == mark_epoch_: already in this recording's marks
  };
  struct Level {
    std::int64_t texels_x = 0, texels_y = 0;  // level size, texels
    std::int64_t tiles_x = 0, tiles_y = 0;    // level size, tiles
    std::int64_t wx = 0, wy = 0;              // window size, tiles
    std::int64_t cx = 0, cy = 0;              // centre tile (stack)
    std::int64_t ox = 0, oy = 0;              // window origin, tiles
    bool stack = false;
    bool placed = false;
    std::uint64_t missing = 0;                // (tile, layer) pairs of the window not resident
    // Derived on every window move (set_window): the texel rectangle [vx0, vx1) × [vy0, vy1)
    // that may be sampled (window minus invalid border, within the level), and the slot of the
    // window's origin tile, so slot lookups need no division.
    std::int64_t vx0 = 0, vx1 = 0, vy0 = 0, vy1 = 0;
    std::int64_t sx0 = 0, sy0 = 0;
    std::vector<Slot> slots;
  };

  std::size_t slot_index(const Level& L, std::int64_t tx, std::int64_t ty) const;
  // Slot of a tile known to lie in the window (no division).
  std::size_t window_slot(const Level& L, std::int64_t tx, std::int64_t ty) const {
    std::int64_t sx = L.sx0 + (tx - L.ox), sy = L.sy0 + (ty - L.oy);
    if (sx >= L.wx) sx -= L.wx;
    if (sy >= L.wy) sy -= L.wy;
    return static_cast<std::size_t>(sy * L.wx + sx);
  }
  void set_window(Level& L, std::int64_t ox, std::int64_t oy);
  // Marks a slot sampled (and records the mark while record_marks is on).
  void mark(const Level& L, int level, std::size_t slot) const {
    const Slot& s = L.slots[slot];
    s.sampled = true;
    if (marks_ && s.marked != mark_epoch_) {
      s.marked = mark_epoch_;
      marks_->push_back(static_cast<std::uint64_t>(level) << 40 | slot);
    }
  }
  // A slot's share of the fingerprint in lane `seed` (0 for an empty slot).
  static std::uint64_t slot_term(std::uint64_t seed, int level, std::size_t slot, const Slot& s);
  // A level's window's share of the fingerprint (0 while unplaced).
  static std::uint64_t window_term(std::uint64_t seed, int level, const Level& L);
  std::int64_t tile_of(std::int64_t texel) const { return tile_shift_ >= 0 ? texel >> tile_shift_ : texel / p_.tile_size; }
  bool in_window(const Level& L, std::int64_t tx, std::int64_t ty) const;
  void recount(Level& L);
  // Centre (hysteresis) and origin a stack level would take for ground texel (gu, gv).
  void target_window(const Level& L, int level, std::int64_t gu, std::int64_t gv, std::int64_t& cx,
                     std::int64_t& cy, std::int64_t& ox, std::int64_t& oy, bool& moved) const;
  std::uint64_t missing_in(const Level& L, std::int64_t ox, std::int64_t oy) const;

  ClipmapParams p_;
  // Per level, the fast path's rectangle [x0, x1) × [y0, y1) of footprint centres (valid rectangle
  // shrunk by the filter margin; empty when the level is incomplete or unplaced). Rebuilt lazily.
  struct FastRect {
    std::int64_t x0, x1, y0, y1;
  };
  void rebuild_fast() const;
  mutable std::vector<FastRect> fast_;
  mutable bool fast_dirty_ = true;
  std::vector<Level> levels_;
  int n_ = 0;
  int first_pyramid_ = 0;
  int clamp_ = 0;
  int tile_shift_ = -1;  // log2(tile size) when it is a power of two
  std::uint32_t full_mask_ = 1;
  bool mark_sampled_ = false;
  mutable std::vector<std::uint64_t>* marks_ = nullptr;
  mutable std::uint8_t mark_epoch_ = 0;  // of the recording under way (1..255; slots start at 0)
  std::uint64_t param_fp_[2] = {0, 0};  // the parameters, per fingerprint lane
  std::uint64_t slot_fp_[2] = {0, 0};   // XOR of slot_term over the slots, per lane
  std::uint64_t window_fp_[2] = {0, 0}; // XOR of window_term over the levels, per lane
  Stats stats_;
};

template <class Importance>
void Clipmap::emit_needs(int finest_active, Importance&& importance, std::vector<Need>& out) const {
  const int from = finest_active > clamp_ ? finest_active : clamp_;
  for (int l = num_levels() - 1; l >= 0; --l) {
    const Level& L = levels_[static_cast<std::size_t>(l)];
    if (L.stack && l < from) continue;
    if (!L.placed || L.missing == 0) continue;
    // Camera tile of this level, for the distance tiebreak: the window centre.
    for (std::int64_t ty = L.oy; ty < L.oy + L.wy; ++ty)
      for (std::int64_t tx = L.ox; tx < L.ox + L.wx; ++tx) {
        const Slot& s = L.slots[slot_index(L, tx, ty)];
        const std::uint32_t have = (s.tx == tx && s.ty == ty) ? s.mask : 0u;
        if (have == full_mask_) continue;
        const std::int64_t dx = tx - L.cx, dy = ty - L.cy;
        const std::uint32_t dist = static_cast<std::uint32_t>((dx < 0 ? -dx : dx) + (dy < 0 ? -dy : dy));
        const std::uint64_t prio = make_priority(static_cast<std::uint32_t>(l), importance(l, tx, ty), dist);
        for (int layer = 0; layer < p_.layers; ++layer)
          if (!(have & (1u << layer)))
            out.push_back(Need{TileKey(static_cast<std::uint32_t>(layer), static_cast<std::uint32_t>(l), tx, ty), prio, false});
      }
  }
}

}  // namespace vtsim
