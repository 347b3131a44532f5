// VT geometry and page table: levels down to one page, partial edge pages, fallback to the finest
// resident ancestor, sparseness at planet scale, the GPU page-table cost model against a brute
// force, and the capacity formulas with Yao 2011's figures.
#include <doctest/doctest.h>

#include <map>
#include <random>
#include <stdexcept>

#include "cache/page_map.h"
#include "cache/page_table.h"

using namespace vtsim;

TEST_CASE("vt geometry: levels go down to a single page, partial edge pages allowed") {
  const VtGeometry g({1 << 20, 1 << 20}, 128, 4);
  CHECK(g.levels() == 14);  // 8192 pages a side at level 0, 1 page at level 13
  CHECK(g.level(0).pages_x == 8192);
  CHECK(g.level(13).pages_x == 1);
  CHECK(g.stored_side() == 136);
  CHECK(g.total_pages() == (std::uint64_t{1} << 26) + (1u << 24) + (1u << 22) + (1u << 20) + (1u << 18) + (1u << 16) +
                               (1u << 14) + (1u << 12) + (1u << 10) + 256 + 64 + 16 + 4 + 1);

  // 1000 × 600 texels in 120-texel pages (RAGE's payload with a 4-texel border in 128): the last
  // column and row are partial.
  const VtGeometry p({1000, 600}, 120, 4);
  CHECK(p.level(0).pages_x == 9);  // 1000 / 120 = 8.33
  CHECK(p.level(0).pages_y == 5);
  CHECK(p.level(1).texels_x == 500);
  CHECK(p.level(1).pages_x == 5);
  CHECK(p.level(3).texels_x == 125);
  CHECK(p.level(3).pages_x == 2);
  CHECK(p.level(4).pages_x == 1);
  CHECK(p.levels() == 5);
  CHECK(p.coarsest_pages(1) == 1);
  CHECK(p.coarsest_pages(2) == 1 + 2 * 1);  // level 3: 125 × 75 texels = 2 × 1 pages

  // A texture no larger than a page has one level.
  CHECK(VtGeometry({100, 50}, 128, 0).levels() == 1);
  CHECK_THROWS_AS(VtGeometry({1024, 1024}, 127, 0), std::invalid_argument);  // odd page
  CHECK_THROWS_AS(VtGeometry({0, 1024}, 128, 0), std::invalid_argument);
}

TEST_CASE("vt geometry: every page of a level lies in its parent (x/2, y/2), edges included") {
  const VtGeometry g({1000, 600}, 120, 0);
  for (int l = 0; l + 1 < g.levels(); ++l) {
    const VtLevel& L = g.level(l);
    for (std::int64_t x = 0; x < L.pages_x; ++x) {
      // Texels of page x at level l map to level l+1 texels [x·P/2, (x·P + P − 1)/2]: one page.
      const std::int64_t first = (x * 120) >> 1, last = std::min<std::int64_t>(x * 120 + 119, L.texels_x - 1) >> 1;
      CHECK(g.page_of(first) == x / 2);
      CHECK(g.page_of(last) == x / 2);
      CHECK(g.valid(l + 1, x / 2, 0));
    }
  }
}

TEST_CASE("page table: a sample falls back to the finest mapped ancestor") {
  PageTable pt(VtGeometry({4096, 4096}, 128, 0));  // 32² pages at level 0, 6 levels
  const int n = pt.geometry().levels();
  CHECK(n == 6);
  CHECK(pt.resolve(0, 5, 7).level == n);  // nothing mapped
  pt.map(page_key(5, 0, 0), 3);
  CHECK(pt.resolve(0, 5, 7).level == 5);
  CHECK(pt.resolve(0, 5, 7).slot == 3);
  pt.map(page_key(2, 0, 0), 9);  // level-2 page (0, 0) covers level-0 pages x, y in [0, 4)
  CHECK(pt.resolve(0, 3, 3).level == 2);
  CHECK(pt.resolve(0, 3, 3).slot == 9);
  CHECK(pt.resolve(0, 4, 3).level == 5);   // outside it
  CHECK(pt.resolve(1, 1, 1).level == 2);
  CHECK(pt.resolve(3, 0, 0).level == 5);   // coarser than the level-2 page: its ancestor
  pt.map(page_key(0, 3, 3), 1);
  CHECK(pt.resolve(0, 3, 3).level == 0);
  CHECK(pt.resolve(0, 3, 2).level == 2);
  pt.unmap(page_key(2, 0, 0));
  CHECK(pt.resolve(0, 3, 2).level == 5);
  CHECK(pt.resolve(0, 3, 3).level == 0);
  CHECK(pt.mapped_pages() == 2);
  CHECK_THROWS_AS(pt.map(page_key(0, 3, 3), 2), std::logic_error);
  CHECK_THROWS_AS(pt.unmap(page_key(1, 0, 0)), std::logic_error);
  CHECK_THROWS_AS(pt.map(page_key(0, 32, 0), 2), std::logic_error);  // not a page of the texture
}

TEST_CASE("page table: a 2^26-texel texture costs memory for mapped pages only") {
  PageTable pt(VtGeometry({std::int64_t{1} << 26, std::int64_t{1} << 26}, 128, 4));
  CHECK(pt.geometry().levels() == 20);
  CHECK(pt.level0_entries() == (std::uint64_t{1} << 38));
  // Dense mip-mapped table: sum of 4^k for k = 0..19 entries = (4^20 − 1) / 3, 4 bytes each.
  CHECK(pt.dense_entries() == ((std::uint64_t{1} << 40) - 1) / 3);
  CHECK(pt.dense_bytes() == 4 * (((std::uint64_t{1} << 40) - 1) / 3));  // ~1.47 TB: impossible
  // Map a whole chain from the root down to a level-0 page far from the origin.
  const std::int64_t x0 = (std::int64_t{1} << 19) - 4, y0 = (std::int64_t{1} << 18) + 11;
  for (int l = 19; l >= 0; --l) pt.map(page_key(l, x0 >> l, y0 >> l), static_cast<std::uint32_t>(l));
  CHECK(pt.mapped_pages() == 20);
  CHECK(pt.sparse_bytes() < 8192);
  CHECK(pt.resolve(0, x0, y0).level == 0);
  CHECK(pt.resolve(0, x0 + 1, y0).level == 1);  // the sibling falls back to the common parent
  // The baked count of the first (root) mapping is the whole dense table.
  CHECK(pt.counters().texels_written_baked >= pt.dense_entries());
}

namespace {

// Brute force: for every entry of every level, the level of the page it resolves to.
std::map<std::uint64_t, int> resolve_all(const PageTable& pt) {
  std::map<std::uint64_t, int> out;
  const VtGeometry& g = pt.geometry();
  for (int l = 0; l < g.levels(); ++l)
    for (std::int64_t y = 0; y < g.level(l).pages_y; ++y)
      for (std::int64_t x = 0; x < g.level(l).pages_x; ++x) {
        const auto r = pt.resolve(l, x, y);
        out[page_key(l, x, y).bits] = r.level * 100000 + static_cast<int>(r.slot == PageTable::kNoSlot ? 99999 : r.slot);
      }
  return out;
}

}  // namespace

TEST_CASE("page table: the baked-fallback update count equals the entries that change, exactly") {
  // 1000 × 700 texels at P = 64: partial pages on both edges; 16 × 11 pages at level 0, 5 levels.
  PageTable pt(VtGeometry({1000, 700}, 64, 0));
  const VtGeometry& g = pt.geometry();
  std::vector<TileKey> all;
  for (int l = 0; l < g.levels(); ++l)
    for (std::int64_t y = 0; y < g.level(l).pages_y; ++y)
      for (std::int64_t x = 0; x < g.level(l).pages_x; ++x) all.push_back(page_key(l, x, y));
  std::mt19937_64 rng(5);
  std::uint32_t next_slot = 0;
  auto before = resolve_all(pt);
  for (int op = 0; op < 400; ++op) {
    const TileKey p = all[rng() % all.size()];
    const std::uint64_t baked0 = pt.counters().texels_written_baked;
    if (pt.mapped(p)) pt.unmap(p);
    else pt.map(p, next_slot++);
    const auto after = resolve_all(pt);
    std::uint64_t changed = 0;
    for (const auto& [k, v] : after) changed += before.at(k) != v;
    REQUIRE(pt.counters().texels_written_baked - baked0 == changed);
    before = after;
  }
  CHECK(pt.counters().entries_written == 400);
}

TEST_CASE("page map: insert, overwrite, erase with backward shift, growth") {
  PageMap<std::uint32_t> m;
  std::map<std::uint64_t, std::uint32_t> ref;
  std::mt19937_64 rng(11);
  for (int i = 0; i < 20000; ++i) {
    const std::uint64_t k = rng() % 3000;
    if (rng() % 3 == 0) {
      CHECK(m.erase(k) == (ref.erase(k) == 1));
    } else {
      const auto v = static_cast<std::uint32_t>(rng());
      m.put(k, v);
      ref[k] = v;
    }
  }
  CHECK(m.size() == ref.size());
  for (const auto& [k, v] : ref) {
    const std::uint32_t* f = m.find(k);
    REQUIRE(f);
    CHECK(*f == v);
  }
  std::size_t n = 0;
  m.for_each([&](std::uint64_t k, std::uint32_t v) {
    CHECK(ref.at(k) == v);
    ++n;
  });
  CHECK(n == ref.size());
  CHECK_THROWS_AS(m.put(PageMap<std::uint32_t>::kEmpty, 1), std::invalid_argument);
}

TEST_CASE("vt capacity: RAGE's 128K texture and Yao 2011's arithmetic") {
  VtCapacityInput in;
  in.extent = {131072, 131072};
  in.page_size = 128;
  in.border = 0;
  in.bytes_per_texel = 4.0;
  in.disk_bytes_per_texel = 4.0;
  in.screen_w = 1680;
  in.screen_h = 1050;
  in.overdraw = 3.0;
  in.redundancy = 6.0;
  in.texels_per_pixel = 1.0;
  const VtCapacity c = vt_capacity(in);
  // Yao 2011 §3.2: 1024 × 1024 pages at the finest level, so a 1024² page table.
  CHECK(c.page_table_level0_side_x == 1024);
  CHECK(c.pages_level0 == 1024 * 1024);
  CHECK(c.levels == 11);  // 1024 pages a side down to 1: 11 levels
  CHECK(c.page_table_entries == (std::uint64_t{1} << 20) + (1 << 18) + (1 << 16) + (1 << 14) + (1 << 12) + (1 << 10) + 256 + 64 + 16 + 4 + 1);
  // Yao 2011 §2: 6 screens × 3 overdraw × 1680 × 1050 × 4 B = 127,008,000 B (121.1 MiB; Yao 2011
  // says "120MB").
  CHECK(c.screen_texels == doctest::Approx(6.0 * 3.0 * 1680 * 1050));
  CHECK(c.pool_pages == 1938);  // ceil(31,752,000 / 16384)
  CHECK(c.pool_bytes == doctest::Approx(1938.0 * 16384 * 4));

  // Yao 2011 §5: 512-texel pages and a 4096² page table address 4096 × 512 = 2,097,152 texels a
  // side; 2^42 texels ("4096 G" is texels) = 16 TiB at 4 bytes per texel, 21.3 TiB with its mip levels.
  VtCapacityInput s5 = in;
  s5.extent = {2097152, 2097152};
  s5.page_size = 512;
  const VtCapacity c5 = vt_capacity(s5);
  CHECK(c5.page_table_level0_side_x == 4096);
  CHECK(c5.levels == 13);  // 4096 pages a side down to one 512² page
  CHECK(c5.payload_texels == ((std::uint64_t{1} << 44) - (std::uint64_t{1} << 18)) / 3);  // sum 4^k, k = 9..21
  CHECK(c5.pages_level0 * 512 * 512 * 4 == (std::uint64_t{1} << 44));      // level 0 alone: 16 TiB

  CHECK_THROWS_AS(vt_capacity([&] { auto b = in; b.screen_w = 0; return b; }()), std::invalid_argument);
  CHECK_THROWS_AS(vt_capacity([&] { auto b = in; b.page_size = 7; return b; }()), std::invalid_argument);
}
