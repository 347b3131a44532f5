#pragma once
// VT Terrain Design's terrain (after Chen 2015, "Adaptive Virtual Texture Rendering in Far Cry 4"):
// a clipmap whose levels are *produced* — rendered from tiling brush textures blended through
// per-sector masks, plus decals — instead of read from the store. docs/produced.md, "The terrain
// (produced clipmap)".
//
// World: sectors_x × sectors_y sectors of sector_m metres, each blending brushes_per_sector brushes
// (brush_size² at mip 0, one brush tile per brush_period_m). Brush mips stream from disk through the
// same RAM cache as tiles, as keys of their own layer (kBrushLayer: level = brush mip, x = sector
// index, y = brush index), sized by tile_sizes(). Clipmap level l renders from brush mip
// m(l) = min(l + mip_offset, brush_tree_levels − 1), mip_offset = log2(brush texel density /
// texture density): the quadtree node whose resolution matches the level's texels. A produced tile
// is needed only once every brush mip it samples is committed; until then its brushes are needed
// (with its priority). Brushes no placed window (or incomplete pyramid level) covers are released.
// The pyramid (levels <= clipsize) is produced once at the start (the Clipmap never moves it).
// Decals: seeded static decals, and footprints every footprint_every_m of camera travel that mark
// the resident tiles under them in the finest footprint_levels levels dirty: needed again,
// produced again, while the old tile stays sampled.
//
// Complexity: emit_needs O(missing window tiles × sectors per tile × brushes); the brush needed-set
// is recomputed only when a window moved or a pyramid level completed, O(brush mips × sectors ×
// brushes). Single-threaded.
#include <memory>
#include <unordered_map>
#include <unordered_set>

#include "cache/clipmap.h"
#include "cache/vram_arena.h"
#include "stream/produce/decal_layer.h"
#include "stream/system/clipmap_backed.h"
#include "stream/system/feedback.h"
#include "stream/system/i_system.h"
#include "stream/system/system_caps.h"

namespace vtsim {

// The config's [terrain] section (VT Terrain Design's figures are the defaults).
struct TerrainConfig {
  int sectors_x = 16;               // sectors along x (VT Terrain Design: 16 × 512 m = 8192 m)
  int sectors_y = 16;               // sectors along y
  double sector_m = 512.0;          // sector side, m
  int brushes_per_sector = 12;      // brushes a sector blends (<= 16: four RGBA masks, a 4×4 atlas)
  int brush_size = 1024;            // brush mip 0 side, texels (a power of two)
  double brush_period_m = 1.0;      // ground covered by one brush tile, m (1024/m ≈ 10 texels/cm)
  int brush_tree_levels = 5;        // brush quadtree levels: leaves hold mip 0, each level up one mip coarser
  double brush_compression = 1.0;   // decoded / disk bytes of a brush mip (1 = raw on disk)
  std::string brush_files;          // real clock: brush images (comma-separated files or patterns); empty = value noise
  int mask_size = 512;              // mask texels a side per sector (RGBA: 4 brush weights each)
  int decals_static = 4096;         // seeded static decals over the whole terrain
  double decal_size_m = 4.0;        // static decal side, m
  std::int64_t decal_seed = 2;      // seed of the static decals' positions
  double footprint_every_m = 0.75;  // a footprint decal per this much camera travel, m; 0 = none
  double footprint_size_m = 0.3;    // footprint side, m
  int footprint_levels = 4;         // finest levels a footprint re-renders (its resident tiles there are invalidated)
};

// `vtsim capacity --system terrain`: VT Terrain Design's figures recomputed (docs/produced.md, "Capacity").
struct TerrainCapacity {
  std::int64_t texels_side_x = 0, texels_side_y = 0;  // level-0 texture extent
  double stored_equiv_bytes = 0;        // level-0 texels × 4 B: what storing the texels would take
  std::uint64_t brushes = 0;            // sectors × brushes_per_sector
  std::uint64_t brush_bytes_mip0 = 0;   // brushes × brush_size² × 4 B
  std::uint64_t brush_bytes_all_mips = 0;  // with every mip down to 1×1
  std::uint64_t masks = 0;              // sectors × ceil(brushes / 4)
  std::uint64_t mask_bytes = 0;         // masks × mask_size² × 4 B
  int full_levels = 0;                  // levels kept at clipsize² (stack + the first pyramid level)
  std::uint64_t clipmap_full_levels_bytes = 0;  // full_levels × clipsize² × 4 B (VT Terrain Design's 208 MiB)
  std::vector<int> level_mip;           // per stack level: the brush mip it renders from
  std::vector<int> level_sectors;       // per stack level: sectors under its window (camera at cx, cy)
  std::uint64_t brush_resident_bytes = 0;  // union over stack levels: sectors × brushes × mip bytes
  std::vector<std::uint64_t> brush_resident_by_mip;
};
TerrainCapacity terrain_capacity(const TerrainConfig& t, double texels_per_m, int clipsize, double cam_x_m, double cam_y_m);

class TerrainSystem final : public ClipmapBacked {
 public:
  static constexpr std::uint32_t kBrushLayer = TileKey::kMaxLayers - 1;
  static constexpr int kMaxBrushes = 16;

  using Config = TerrainConfig;
  TerrainSystem(const SystemSetup& s, const ClipmapConfig& cc, const TerrainConfig& t);
  static void validate(const SystemSetup& s, const ClipmapConfig& cc, const TerrainConfig& t, const ThrottleParams& th);
  static int store_levels(const SystemSetup& s, const ClipmapConfig&) { return mip_level_count(s.extent); }
  static constexpr std::string_view kStoreLevels = "until the produce stage runs, the terrain's tiles are read like a clipmap's";
  static VramArena vram_arena(const SystemSetup& s, const ClipmapConfig& c, std::vector<std::uint32_t> layer_bytes,
                              std::uint64_t host_limit);
  static constexpr std::string_view kVramField = "clipmap.clipsize";
  // Its name in the table (run.system) and what it can do.
  static constexpr char kName[] = "terrain";
  static constexpr SystemCaps kCaps{.produces_tiles = true, .clip_window = true, .capacity = CapacityReport::produced};

  void begin_frame(const SystemFrame& f) override;
  void missing_bytes_by_level(std::vector<std::uint64_t>& out) const override;
  void emit_needs(std::vector<Need>& out) override;
  std::uint32_t throttled_needs() const override { return 0; }
  bool commit(TileKey key, int frame) override;
  bool accepts(TileKey key) const override;
  bool produced(TileKey key, ProduceWork& work) const override;
  bool full_tile_work(ProduceWork& work) const override;
  bool tile_sizes(TileKey key, std::uint64_t& disk_bytes, std::uint64_t& decoded_bytes) const override;
  std::vector<std::string> frame_counter_names() const override;
  void frame_counters(SystemCounters& out) const override;
  nlohmann::json stats_json() const override;
  std::uint64_t vram_thrash() const override { return 0; }
  std::uint64_t evicted_unsampled_bytes() const override;

  int brush_mip(int level) const;           // m(l)
  bool brush_resident(int mip, int sector, int brush) const { return resident_[idx(mip, sector, brush)] != 0; }
  int sector_texels() const { return static_cast<int>(sector_texels_); }
  // The sectors a tile of `level` covers, [x0, x1] × [y0, y1].
  void tile_sectors(int level, std::int64_t tx, std::int64_t ty, int& x0, int& x1, int& y0, int& y1) const;
  std::uint64_t brush_bytes_resident() const { return brush_bytes_; }
  std::uint64_t brush_loads() const { return brush_loads_; }
  std::uint64_t brush_releases() const { return brush_releases_; }
  std::uint64_t invalidations() const { return invalidations_; }
  std::uint64_t footprints() const { return decals_->footprints(); }
  std::uint64_t produced_tiles(int level) const { return produced_[static_cast<std::size_t>(level)]; }
  std::uint64_t gated_needs() const { return gated_; }
  // Places a footprint decal at a world position now (what begin_frame does every footprint_every_m).
  void add_footprint(double x_m, double y_m);
  // The decals, for the real clock's producer to draw what this system counts (thread-safe reads).
  std::shared_ptr<const produce::DecalLayer> decal_layer() const { return decals_; }

 private:
  std::size_t idx(int mip, int sector, int brush) const {
    return (static_cast<std::size_t>(mip) * static_cast<std::size_t>(sectors_) + static_cast<std::size_t>(sector)) * kMaxBrushes +
           static_cast<std::size_t>(brush);
  }
  std::uint64_t brush_decoded(int mip) const;
  void recompute_needed();
  std::uint32_t count_decals(int level, std::int64_t tx, std::int64_t ty, std::uint64_t& texels) const;  // texels: those they touch
  void gate(const Need& n, std::vector<Need>& out, bool prefetch);

  SystemSetup s_;
  TerrainConfig t_;
  std::int64_t sector_texels_ = 0;
  int sectors_ = 0;
  int mip_offset_ = 0;
  std::int64_t gu_ = 0, gv_ = 0, fu_ = 0, fv_ = 0;
  bool prefetch_ = false;
  int finest_active_ = 0;
  int frame_ = 0;
  bool needed_dirty_ = true;
  std::vector<std::uint8_t> resident_, needed_;
  std::vector<int> emitted_frame_;
  std::shared_ptr<produce::DecalLayer> decals_;  // static decals and footprints (shared with the real clock's producer)
  std::uint64_t footprints_dropped_ = 0;         // footprints past DecalLayer::kMaxFootprints
  bool have_last_ = false;
  double last_x_ = 0, last_y_ = 0, travel_ = 0;
  std::unordered_set<std::uint64_t> dirty_;  // resident tile keys a footprint invalidated
  std::vector<Need> tmp_;
  std::vector<std::uint64_t> produced_;
  std::uint64_t brush_bytes_ = 0, brush_loads_ = 0, brush_releases_ = 0, invalidations_ = 0, gated_ = 0;
  std::uint64_t stale_brush_commits_ = 0;
  std::uint32_t frame_produced_ = 0, frame_brush_loads_ = 0, frame_releases_ = 0, frame_gated_ = 0;
};

}  // namespace vtsim
