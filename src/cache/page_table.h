#pragma once
// Virtual texturing (Yao 2011, id Tech 5 / RAGE): the geometry of a virtual texture cut into
// pages per mip level, and the page table that maps virtual pages to physical pool slots with
// fallback to the finest resident ancestor (Yao 2011 §3.2 "页表贴图"). docs/vt.md.
//
// Geometry. Level l of a W×H texture is ceil(W/2^l) × ceil(H/2^l) texels (docs/architecture.md),
// cut into pages of P×P payload texels (stored (P+2B)² with a border of B texels for filtering);
// the last page of a row or column may be partial (P need not divide the level: the clipmap
// allows any texture size, and so does VT; a partial page is stored as a whole page). Levels go
// down to the first one that is a single page. P must be even, so that every page of level l lies
// inside exactly one page of level l+1 — its parent (x/2, y/2) — and the pages form a quadtree.
//
// The page table is sparse (a hash of mapped pages): a 2^26-texel texture at P = 128 has 2^38
// level-0 pages, which no dense table could hold. It also reports what the equivalent GPU
// page-table texture would cost (docs/vt.md "Page table"):
//  - size: a mip-mapped indirection texture, one entry per page per level, kEntryBytes each;
//  - update cost, two ways: `entries_written` (1 per map or unmap: a table whose shader walks up
//    to the finest resident ancestor) and `texels_written_baked` (a table with the fallback baked
//    in, every entry holding the slot of its finest resident ancestor: mapping or unmapping page p
//    rewrites every entry of p's sub-pyramid not covered by a finer mapped page). The baked count
//    is maintained exactly in O(levels) per map/unmap by keeping, for every unmapped page with a
//    mapped descendant, how many entries of its sub-pyramid are covered.
//
// Complexity: map/unmap O(levels) expected; peek O(1); resolve O(levels - level). Memory: O(mapped
// pages × levels). Thread-safety: none (the frame loop); const members are safe concurrently while
// nobody mutates. generation() changes on every map and unmap (for callers that memoise lookups).
#include <cstdint>
#include <optional>
#include <vector>

#include "cache/page_map.h"
#include "core/tile_key.h"
#include "core/view.h"

namespace vtsim {

struct VtLevel {
  std::int64_t texels_x = 0, texels_y = 0;  // level size, texels
  std::int64_t pages_x = 0, pages_y = 0;    // level size, pages (the last ones may be partial)
};

class VtGeometry {
 public:
  // Throws std::invalid_argument for an empty texture, a page size that is not even and >= 2, or
  // more pages a side than a TileKey holds (2^27).
  VtGeometry(TextureExtent extent, int page_size, int border);

  int levels() const { return static_cast<int>(levels_.size()); }
  int page_size() const { return page_; }
  int border() const { return border_; }
  int stored_side() const { return page_ + 2 * border_; }  // texels a side of a stored page
  TextureExtent extent() const { return extent_; }
  const VtLevel& level(int l) const { return levels_[static_cast<std::size_t>(l)]; }
  bool pow2_page() const { return shift_ >= 0; }

  std::uint64_t pages_at(int l) const;
  std::uint64_t total_pages() const;  // every level
  // Pages of the `n` coarsest levels (what vt.locked_levels pins).
  std::uint64_t coarsest_pages(int n) const;
  // Entries in the sub-pyramid of page (l, x, y): the page and every descendant down to level 0,
  // clipped to the texture.
  std::uint64_t subpyramid_entries(int l, std::int64_t x, std::int64_t y) const;

  // Page coordinate of level-l texel t (floor; t >= 0).
  std::int64_t page_of(std::int64_t t) const { return shift_ >= 0 ? t >> shift_ : t / page_; }
  bool valid(int l, std::int64_t x, std::int64_t y) const {
    return l >= 0 && l < levels() && x >= 0 && y >= 0 && x < level(l).pages_x && y < level(l).pages_y;
  }

 private:
  TextureExtent extent_;
  int page_ = 0, border_ = 0, shift_ = -1;
  std::vector<VtLevel> levels_;
};

inline TileKey page_key(int level, std::int64_t x, std::int64_t y) {
  return TileKey(0, static_cast<std::uint32_t>(level), x, y);
}
inline TileKey parent_page(TileKey p) { return page_key(static_cast<int>(p.level()) + 1, p.x() >> 1, p.y() >> 1); }

class PageTable {
 public:
  static constexpr std::uint32_t kEntryBytes = 4;  // e.g. RGBA8: slot x, slot y, level, spare
  static constexpr std::uint32_t kNoSlot = ~std::uint32_t{0};

  explicit PageTable(VtGeometry geo);
  const VtGeometry& geometry() const { return geo_; }

  // Maps a page (all layers resident) to a pool slot. Throws std::logic_error if it is mapped
  // already or is not a page of the texture.
  void map(TileKey page, std::uint32_t slot);
  // Unmaps a page; throws std::logic_error if it is not mapped.
  void unmap(TileKey page);

  // Slot of a mapped page, or kNoSlot (non-promoting).
  std::uint32_t peek(TileKey page) const;
  bool mapped(TileKey page) const { return peek(page) != kNoSlot; }

  // The finest mapped page at a level >= `level` covering page (level, x, y): its level and slot;
  // level == levels() and kNoSlot when none is mapped.
  struct Resolved {
    int level = 0;
    std::uint32_t slot = kNoSlot;
  };
  Resolved resolve(int level, std::int64_t x, std::int64_t y) const;

  std::size_t mapped_pages() const { return map_.size(); }
  std::uint64_t generation() const { return generation_; }

  // GPU page-table texture equivalents (docs/vt.md).
  std::uint64_t dense_entries() const { return geo_.total_pages(); }
  std::uint64_t dense_bytes() const { return dense_entries() * kEntryBytes; }
  std::uint64_t level0_entries() const { return geo_.pages_at(0); }
  // Bytes the sparse structures hold now (tables, including their empty slots).
  std::uint64_t sparse_bytes() const { return map_.memory_bytes() + covered_.memory_bytes(); }
  struct Counters {
    std::uint64_t maps = 0, unmaps = 0;
    std::uint64_t entries_written = 0;       // one per map or unmap
    std::uint64_t texels_written_baked = 0;  // fallback-baked table: entries rewritten
  };
  const Counters& counters() const { return counters_; }

 private:
  std::uint64_t covered_of(TileKey page) const;  // entries of page's sub-pyramid covered at or below it
  std::uint64_t children_covered(TileKey page) const;
  void propagate(TileKey page, std::int64_t delta);

  VtGeometry geo_;
  PageMap<std::uint32_t> map_;         // mapped page -> slot
  PageMap<std::uint64_t> covered_;     // unmapped page with mapped descendants -> covered entries
  std::uint64_t generation_ = 0;
  Counters counters_;
};

// What a virtual texture costs on disk and in page tables, and Yao 2011 §2's estimate of the
// physical pool a screen needs (`vtsim capacity --system vt`; formulas in docs/vt.md "Capacity").
struct VtCapacityInput {
  TextureExtent extent{1 << 20, 1 << 20};  // level-0 texels
  int page_size = 128;                     // P, payload texels a side
  int border = 4;                          // B, texels a side
  double bytes_per_texel = 4.0;            // decoded (VRAM), all layers summed
  double disk_bytes_per_texel = 4.0;       // on disk, all layers summed (after compression)
  int screen_w = 1920, screen_h = 1080;    // pixels
  double overdraw = 3.0;                   // surfaces drawn per pixel (Yao 2011 §2: 3)
  double redundancy = 1.0;                 // screen-sized textures of cache slack (Yao 2011 §2: 6)
  double texels_per_pixel = 1.0;           // at the desired level (Yao 2011 §2: 1)
};
struct VtCapacity {
  int levels = 0;
  std::uint64_t pages = 0, pages_level0 = 0;  // all levels; level 0
  std::uint64_t payload_texels = 0;           // texels of every level (partial pages exact)
  std::uint64_t stored_texels = 0;            // pages × (P+2B)²: what the page store holds
  double disk_bytes = 0, decoded_bytes = 0;   // the whole store, bytes
  std::uint64_t page_table_entries = 0;       // dense mip-mapped GPU page table, entries
  std::uint64_t page_table_bytes = 0;         // × PageTable::kEntryBytes
  std::uint64_t page_table_level0_side_x = 0, page_table_level0_side_y = 0;  // level-0 table, texels
  double screen_texels = 0;                   // redundancy × overdraw × screen × texels/pixel
  std::uint64_t pool_pages = 0;               // ceil(screen_texels / P²)
  double pool_bytes = 0;                      // pool_pages × (P+2B)² × bytes/texel
};
// Throws std::invalid_argument naming the bad parameter.
VtCapacity vt_capacity(const VtCapacityInput& in);

}  // namespace vtsim
