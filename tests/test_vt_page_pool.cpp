// VT physical page pool: LRU order by last-used frame, pages used this frame are safe, rescue of
// a pending victim, release, locked levels never evicted, the budget never exceeded, the one
// eviction hook.
#include <doctest/doctest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "cache/page_pool.h"
#include "cache/page_table.h"

using namespace vtsim;

namespace {

TileKey pg(int l, std::int64_t x, std::int64_t y = 0) { return page_key(l, x, y); }

// Reserves and commits every layer of a page in one go.
std::uint32_t load(PagePool& pool, TileKey p, int frame, int layers = 1) {
  const std::uint32_t s = pool.reserve(p, frame);
  if (s == PagePool::kNoSlot) return s;
  for (int l = 0; l < layers; ++l) REQUIRE(pool.commit(p, l, frame).slot == s);
  return s;
}

}  // namespace

TEST_CASE("page pool: eviction takes the least recently used page, by last-used frame") {
  std::vector<PagePool::Removed> removed;
  PagePool pool(4, 1, 99, [&](const PagePool::Removed& r) { removed.push_back(r); });
  for (int i = 0; i < 4; ++i) REQUIRE(load(pool, pg(0, i), i) != PagePool::kNoSlot);  // A0..A3 used in frames 0..3
  CHECK(pool.free_slots() == 0);
  pool.touch(pg(0, 0), 10);  // A0 most recent; order now A1, A2, A3, A0
  pool.touch(pg(0, 2), 11);  // A1, A3, A0, A2
  const auto order = pool.lru_order();
  REQUIRE(order.size() == 4);
  CHECK(order[0] == pg(0, 1));
  CHECK(order[1] == pg(0, 3));
  CHECK(order[2] == pg(0, 0));
  CHECK(order[3] == pg(0, 2));
  CHECK(pool.used_within(11, 2) == 2);   // A0 (frame 10), A2 (frame 11)
  CHECK(pool.used_within(11, 9) == 3);   // and A3 (frame 3)
  CHECK(pool.used_within(11, 20) == 4);
  CHECK(pool.used_within(9, 5) == 0);
  // New pages evict A1 then A3, at their first layer's commit.
  const std::uint32_t s1 = pool.reserve(pg(0, 10), 12);
  CHECK(pool.pending_evictions() == 1);
  CHECK(pool.resident(pg(0, 1)));  // still resident (and sampled) until the new page arrives
  CHECK(removed.empty());
  CHECK(pool.commit(pg(0, 10), 0, 12).complete);
  REQUIRE(removed.size() == 1);
  CHECK(removed[0].page == pg(0, 1));
  CHECK(removed[0].slot == s1);
  CHECK(removed[0].complete);
  CHECK(removed[0].reason == PagePool::Removal::kEvicted);
  CHECK(!pool.resident(pg(0, 1)));
  load(pool, pg(0, 11), 12);
  CHECK(removed.back().page == pg(0, 3));
  CHECK(pool.stats().evictions == 2);
  CHECK(pool.occupied() == 4);
}

TEST_CASE("page pool: pages used in the current frame are never victims") {
  PagePool pool(3, 1, 99);
  for (int i = 0; i < 3; ++i) load(pool, pg(0, i), 5);
  for (int i = 0; i < 3; ++i) pool.touch(pg(0, i), 6);
  CHECK(pool.reserve(pg(1, 0), 6) == PagePool::kNoSlot);  // all three in use this frame
  CHECK(pool.stats().reserve_failures == 1);
  CHECK(pool.reserve(pg(1, 0), 7) != PagePool::kNoSlot);  // next frame they are evictable
}

TEST_CASE("page pool: a victim needed again before its eviction is rescued") {
  int hooks = 0;
  PagePool pool(2, 1, 99, [&](const PagePool::Removed&) { ++hooks; });
  load(pool, pg(0, 0), 1);
  load(pool, pg(0, 1), 2);
  const std::uint32_t s = pool.reserve(pg(0, 5), 3);  // victim: page 0 (least recent)
  REQUIRE(s == pool.slot_of(pg(0, 0)));
  CHECK(pool.pending_evictions() == 1);
  const PagePool::Touch t = pool.touch(pg(0, 0), 3);  // needed again: rescued
  CHECK(t.rescued);
  CHECK(t.lost == pg(0, 5));
  CHECK(t.slot == s);
  CHECK(pool.stats().rescues == 1);
  CHECK(pool.pending_evictions() == 0);
  CHECK(!pool.reserved(pg(0, 5)));
  CHECK(pool.resident(pg(0, 0)));
  CHECK(pool.commit(pg(0, 5), 0, 3).slot == PagePool::kNoSlot);  // its upload finds no slot
  CHECK(hooks == 0);
  // Reserving again takes the other page (page 1, last used in frame 2).
  CHECK(pool.reserve(pg(0, 5), 3) == pool.slot_of(pg(0, 1)));
}

TEST_CASE("page pool: releasing a reservation returns its victim in LRU order") {
  PagePool pool(3, 1, 99);
  load(pool, pg(0, 0), 1);
  load(pool, pg(0, 1), 2);
  load(pool, pg(0, 2), 3);
  pool.reserve(pg(1, 0), 4);  // victim page 0
  pool.reserve(pg(1, 1), 4);  // victim page 1
  CHECK(pool.pending_evictions() == 2);
  CHECK(pool.lru_order() == std::vector<TileKey>{pg(0, 2)});
  pool.release(pg(1, 1));  // page 1 back
  pool.release(pg(1, 0));  // page 0 back, behind page 1 (older)
  CHECK(pool.lru_order() == std::vector<TileKey>{pg(0, 0), pg(0, 1), pg(0, 2)});
  CHECK(pool.stats().released_victims == 2);
  CHECK(pool.pending_evictions() == 0);
  pool.release(pg(7, 7));  // no reservation: nothing happens
  CHECK(pool.resident_pages() == 3);
}

TEST_CASE("page pool: layers fill a slot, a released partial page leaves through the hook") {
  std::vector<PagePool::Removed> removed;
  PagePool pool(2, 3, 99, [&](const PagePool::Removed& r) { removed.push_back(r); });
  const std::uint32_t s = pool.reserve(pg(0, 0), 1);
  auto c = pool.commit(pg(0, 0), 1, 1);
  CHECK(c.first_layer);
  CHECK(!c.complete);
  CHECK(pool.resident_mask(pg(0, 0)) == 0b010);
  CHECK(!pool.resident(pg(0, 0)));
  c = pool.commit(pg(0, 0), 0, 2);
  CHECK(!c.first_layer);
  CHECK(pool.commit(pg(0, 0), 2, 2).complete);
  CHECK(pool.resident(pg(0, 0)));
  CHECK(pool.slot_of(pg(0, 0)) == s);
  CHECK(pool.commit(pg(0, 0), 5, 2).slot == PagePool::kNoSlot);  // no such layer / no reservation

  pool.reserve(pg(0, 1), 3);
  pool.commit(pg(0, 1), 0, 3);
  pool.release(pg(0, 1));  // no longer wanted while filling: the slot is freed
  REQUIRE(removed.size() == 1);
  CHECK(removed[0].page == pg(0, 1));
  CHECK(removed[0].reason == PagePool::Removal::kReleased);
  CHECK(removed[0].mask == 1);
  CHECK(!removed[0].complete);
  CHECK(pool.free_slots() == 1);
  CHECK(pool.occupied() == 1);
}

TEST_CASE("page pool: locked levels are never evicted and the budget is never exceeded (random ops)") {
  constexpr std::uint32_t kSlots = 24;
  constexpr int kLockFrom = 5;
  std::set<std::uint64_t> in_slot;  // pages the hook has not removed
  std::uint64_t hook_calls = 0;
  PagePool pool(kSlots, 2, kLockFrom, [&](const PagePool::Removed& r) {
    ++hook_calls;
    REQUIRE(in_slot.erase(r.page.bits) == 1);  // once per page that was in a slot
    REQUIRE(r.page.level() < static_cast<std::uint32_t>(kLockFrom));
  });
  std::mt19937_64 rng(3);
  // Locked pages first (level 5 and 6: 4 + 1 pages).
  std::vector<TileKey> locked = {pg(6, 0), pg(5, 0, 0), pg(5, 1, 0), pg(5, 0, 1), pg(5, 1, 1)};
  for (TileKey p : locked) {
    REQUIRE(load(pool, p, 0, 2) != PagePool::kNoSlot);
    in_slot.insert(p.bits);
  }
  std::vector<TileKey> reserved;
  for (int frame = 1; frame < 3000; ++frame) {
    for (int k = 0; k < 6; ++k) {
      const TileKey p = pg(static_cast<int>(rng() % 3), static_cast<std::int64_t>(rng() % 12), static_cast<std::int64_t>(rng() % 4));
      switch (rng() % 4) {
        case 0:
          pool.touch(p, frame);
          break;
        case 1:
          if (pool.slot_of(p) == PagePool::kNoSlot && pool.reserve(p, frame) != PagePool::kNoSlot) reserved.push_back(p);
          break;
        case 2:
          if (!reserved.empty()) {
            const TileKey r = reserved[rng() % reserved.size()];
            if (pool.reserved(r)) {
              const auto c = pool.commit(r, static_cast<int>(rng() % 2), frame);
              if (c.first_layer) in_slot.insert(r.bits);
            }
          }
          break;
        default:
          if (!reserved.empty()) pool.release(reserved[rng() % reserved.size()]);
          break;
      }
      REQUIRE(pool.occupied() <= kSlots);
      REQUIRE(pool.occupied() == in_slot.size());
      REQUIRE(pool.occupied() + pool.free_slots() <= kSlots);
    }
    for (TileKey p : locked) REQUIRE(pool.resident(p));
    pool.touch(locked[0], frame);
  }
  CHECK(pool.locked_pages() == 5);
  CHECK(pool.stats().evictions > 100);
  CHECK(pool.stats().rescues > 10);
  CHECK(hook_calls == pool.stats().evictions + pool.stats().partial_released);
  const auto order = pool.lru_order();
  for (std::size_t i = 1; i < order.size(); ++i) CHECK(pool.last_used(order[i - 1]) <= pool.last_used(order[i]));
}
