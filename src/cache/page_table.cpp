#include "cache/page_table.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vtsim {

VtGeometry::VtGeometry(TextureExtent extent, int page_size, int border) : extent_(extent), page_(page_size), border_(border) {
  if (extent.width <= 0 || extent.height <= 0) throw std::invalid_argument("virtual texture: empty texture");
  if (page_size < 2 || page_size % 2 != 0)
    throw std::invalid_argument("virtual texture: the page size must be even and >= 2 (got " + std::to_string(page_size) + ")");
  if (border < 0) throw std::invalid_argument("virtual texture: negative border");
  if (std::has_single_bit(static_cast<unsigned>(page_size))) shift_ = std::countr_zero(static_cast<unsigned>(page_size));
  std::int64_t w = extent.width, h = extent.height;
  for (;;) {
    VtLevel L;
    L.texels_x = w;
    L.texels_y = h;
    L.pages_x = (w + page_size - 1) / page_size;
    L.pages_y = (h + page_size - 1) / page_size;
    if (L.pages_x - 1 > TileKey::kMaxCoord || L.pages_y - 1 > TileKey::kMaxCoord)
      throw std::invalid_argument("virtual texture: more than 2^27 pages a side: use larger pages");
    levels_.push_back(L);
    if (L.pages_x == 1 && L.pages_y == 1) break;  // down to a single page
    w = (w + 1) / 2;
    h = (h + 1) / 2;
  }
  if (levels_.size() > TileKey::kMaxLevels) throw std::invalid_argument("virtual texture: too many levels");
}

std::uint64_t VtGeometry::pages_at(int l) const {
  const VtLevel& L = level(l);
  return static_cast<std::uint64_t>(L.pages_x) * static_cast<std::uint64_t>(L.pages_y);
}

std::uint64_t VtGeometry::total_pages() const {
  std::uint64_t n = 0;
  for (int l = 0; l < levels(); ++l) n += pages_at(l);
  return n;
}

std::uint64_t VtGeometry::coarsest_pages(int n) const {
  std::uint64_t s = 0;
  for (int l = std::max(0, levels() - n); l < levels(); ++l) s += pages_at(l);
  return s;
}

std::uint64_t VtGeometry::subpyramid_entries(int l, std::int64_t x, std::int64_t y) const {
  std::uint64_t s = 0;
  for (int k = l; k >= 0; --k) {
    const int d = l - k;
    const VtLevel& L = level(k);
    const std::int64_t x0 = x << d, y0 = y << d;
    const std::int64_t nx = std::min(L.pages_x, (x + 1) << d) - x0, ny = std::min(L.pages_y, (y + 1) << d) - y0;
    if (nx <= 0 || ny <= 0) break;  // outside the texture at this level, so at every finer one
    s += static_cast<std::uint64_t>(nx) * static_cast<std::uint64_t>(ny);
  }
  return s;
}

PageTable::PageTable(VtGeometry geo) : geo_(std::move(geo)) {}

std::uint32_t PageTable::peek(TileKey page) const {
  const std::uint32_t* s = map_.find(page.bits);
  return s ? *s : kNoSlot;
}

PageTable::Resolved PageTable::resolve(int level, std::int64_t x, std::int64_t y) const {
  for (int l = level; l < geo_.levels(); ++l, x >>= 1, y >>= 1)
    if (const std::uint32_t* s = map_.find(page_key(l, x, y).bits)) return {l, *s};
  return {geo_.levels(), kNoSlot};
}

std::uint64_t PageTable::covered_of(TileKey page) const {
  if (map_.contains(page.bits))
    return geo_.subpyramid_entries(static_cast<int>(page.level()), page.x(), page.y());
  const std::uint64_t* c = covered_.find(page.bits);
  return c ? *c : 0;
}

std::uint64_t PageTable::children_covered(TileKey page) const {
  const int l = static_cast<int>(page.level());
  if (l == 0) return 0;
  std::uint64_t s = 0;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const std::int64_t cx = 2 * page.x() + dx, cy = 2 * page.y() + dy;
      if (geo_.valid(l - 1, cx, cy)) s += covered_of(page_key(l - 1, cx, cy));
    }
  return s;
}

// Adds delta to the covered count of every unmapped ancestor up to the first mapped one (whose
// sub-pyramid is wholly covered whatever happens below it).
void PageTable::propagate(TileKey page, std::int64_t delta) {
  for (TileKey a = page; static_cast<int>(a.level()) + 1 < geo_.levels();) {
    a = parent_page(a);
    if (map_.contains(a.bits)) return;
    std::uint64_t* c = covered_.find(a.bits);
    const std::uint64_t v = static_cast<std::uint64_t>(static_cast<std::int64_t>(c ? *c : 0) + delta);
    if (v == 0) covered_.erase(a.bits);
    else if (c) *c = v;
    else covered_.put(a.bits, v);
  }
}

void PageTable::map(TileKey page, std::uint32_t slot) {
  const int l = static_cast<int>(page.level());
  if (page.layer() != 0 || !geo_.valid(l, page.x(), page.y())) throw std::logic_error("PageTable::map: not a page of the texture");
  if (map_.contains(page.bits)) throw std::logic_error("PageTable::map: page already mapped");
  const std::uint64_t all = geo_.subpyramid_entries(l, page.x(), page.y());
  const std::uint64_t below = children_covered(page);
  counters_.texels_written_baked += all - below;  // entries that resolved to a coarser page (or none)
  ++counters_.entries_written;
  ++counters_.maps;
  covered_.erase(page.bits);
  map_.put(page.bits, slot);
  propagate(page, static_cast<std::int64_t>(all - below));
  ++generation_;
}

void PageTable::unmap(TileKey page) {
  if (!map_.erase(page.bits)) throw std::logic_error("PageTable::unmap: page not mapped");
  const int l = static_cast<int>(page.level());
  const std::uint64_t all = geo_.subpyramid_entries(l, page.x(), page.y());
  const std::uint64_t below = children_covered(page);
  counters_.texels_written_baked += all - below;  // they now resolve to an ancestor (or nothing)
  ++counters_.entries_written;
  ++counters_.unmaps;
  if (below) covered_.put(page.bits, below);
  propagate(page, -static_cast<std::int64_t>(all - below));
  ++generation_;
}

VtCapacity vt_capacity(const VtCapacityInput& in) {
  const VtGeometry g(in.extent, in.page_size, in.border);
  if (!(in.bytes_per_texel > 0) || !(in.disk_bytes_per_texel > 0)) throw std::invalid_argument("bytes per texel must be > 0");
  if (in.screen_w <= 0 || in.screen_h <= 0) throw std::invalid_argument("screen: width and height must be > 0");
  if (!(in.overdraw > 0) || !(in.redundancy > 0) || !(in.texels_per_pixel > 0))
    throw std::invalid_argument("overdraw, redundancy and texels per pixel must be > 0");
  VtCapacity c;
  c.levels = g.levels();
  c.pages = g.total_pages();
  c.pages_level0 = g.pages_at(0);
  for (int l = 0; l < g.levels(); ++l)
    c.payload_texels += static_cast<std::uint64_t>(g.level(l).texels_x) * static_cast<std::uint64_t>(g.level(l).texels_y);
  const auto side = static_cast<std::uint64_t>(g.stored_side());
  c.stored_texels = c.pages * side * side;
  c.decoded_bytes = static_cast<double>(c.stored_texels) * in.bytes_per_texel;
  c.disk_bytes = static_cast<double>(c.stored_texels) * in.disk_bytes_per_texel;
  c.page_table_entries = c.pages;
  c.page_table_bytes = c.pages * PageTable::kEntryBytes;
  c.page_table_level0_side_x = static_cast<std::uint64_t>(g.level(0).pages_x);
  c.page_table_level0_side_y = static_cast<std::uint64_t>(g.level(0).pages_y);
  c.screen_texels = in.redundancy * in.overdraw * static_cast<double>(in.screen_w) * static_cast<double>(in.screen_h) *
                    in.texels_per_pixel;
  const double payload = static_cast<double>(in.page_size) * static_cast<double>(in.page_size);
  c.pool_pages = static_cast<std::uint64_t>(std::ceil(c.screen_texels / payload));
  c.pool_bytes = static_cast<double>(c.pool_pages) * static_cast<double>(side * side) * in.bytes_per_texel;
  return c;
}

}  // namespace vtsim
