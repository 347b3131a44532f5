// Replacement policies (src/cache/policy/impl/), the offline simulator (simulate.h) and the
// offline bounds (belady.h): golden miss counts derived by hand on small sequences, the simulator
// against LruCache, the bounds against every policy and against exhaustive search, pinning,
// restore, determinism and errors. docs/cache.md, "Replacement policies and Belady's bound".
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "cache/lru_cache.h"
#include "cache/policy/access.h"
#include "cache/policy/belady.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/simulate.h"
#include "core/tile_key.h"

using namespace vtsim;

namespace {

std::vector<Access> cp_unit(const std::vector<std::uint64_t>& keys) {
  std::vector<Access> out;
  for (std::uint64_t k : keys) out.push_back({k, 1});
  return out;
}

// Silberschatz, Galvin and Gagne, "Operating System Concepts", §10.4 (page replacement): the
// reference string with 3 frames: FIFO 15 faults, OPT 9, LRU 12.
const std::vector<std::uint64_t> kCpTextbook = {7, 0, 1, 2, 0, 3, 0, 4, 2, 3, 0, 3, 2, 1, 2, 0, 1, 7, 0, 1};

// FIFO, for the textbook's third figure only (not a registered policy).
std::uint64_t cp_fifo_misses(const std::vector<std::uint64_t>& keys, std::size_t frames) {
  std::deque<std::uint64_t> q;
  std::uint64_t misses = 0;
  for (std::uint64_t k : keys) {
    if (std::find(q.begin(), q.end(), k) != q.end()) continue;
    ++misses;
    if (q.size() == frames) q.pop_front();
    q.push_back(k);
  }
  return misses;
}

// Random sequences: keys skewed towards small numbers (a hot set and a tail), sizes 1 or 1-9.
std::vector<Access> cp_random(std::uint64_t seed, std::size_t n, std::uint64_t universe, bool sized) {
  std::mt19937_64 rng(seed);
  std::vector<Access> out(n);
  for (Access& a : out) {
    const std::uint64_t r = rng() % universe;
    a.key = rng() % 3 == 0 ? r : r % (universe / 4 + 1);
    a.size = sized ? 1 + (a.key * 7 + 3) % 9 : 1;  // a key's size is constant
  }
  return out;
}

std::vector<std::string> cp_policy_names() {
  std::vector<std::string> names;
  for (const ReplacementPolicyInfo& p : replacement_policies().entries()) names.emplace_back(p.name);
  return names;
}

// The exact optimum by exhaustive search over cache contents (tiny sequences, <= 8 keys).
// demand: every missed key is admitted (unit sizes, evicting one key when full);
// otherwise after each request the cache may keep any subset of what it held plus the key.
std::uint64_t cp_exhaustive_opt(const std::vector<Access>& seq, std::uint64_t capacity, bool demand) {
  std::map<std::uint32_t, std::uint64_t> best = {{0u, 0}};  // key set (bits) -> fewest misses
  auto weight = [&](std::uint32_t set) {
    std::uint64_t sum = 0;
    for (std::uint32_t k = 0; k < 8; ++k)
      if (set >> k & 1u)
        for (const Access& a : seq)
          if (a.key == k) {
            sum += a.size;
            break;
          }
    return sum;
  };
  for (const Access& a : seq) {
    std::map<std::uint32_t, std::uint64_t> next;
    auto offer = [&](std::uint32_t set, std::uint64_t misses) {
      auto [it, fresh] = next.emplace(set, misses);
      if (!fresh) it->second = std::min(it->second, misses);
    };
    const std::uint32_t bit = 1u << a.key;
    for (const auto& [set, misses] : best) {
      const bool hit = (set & bit) != 0;
      const std::uint64_t m = misses + (hit ? 0 : 1);
      if (demand) {
        if (hit || a.size > capacity) {
          offer(set, m);
        } else if (weight(set) + 1 <= capacity) {
          offer(set | bit, m);
        } else {
          for (std::uint32_t k = 0; k < 8; ++k)
            if (set >> k & 1u) offer((set & ~(1u << k)) | bit, m);
        }
      } else {
        const std::uint32_t all = set | bit;
        for (std::uint32_t sub = all;; sub = (sub - 1) & all) {
          if (weight(sub) <= capacity) offer(sub, m);
          if (sub == 0) break;
        }
      }
    }
    best = std::move(next);
  }
  std::uint64_t out = ~std::uint64_t{0};
  for (const auto& [set, misses] : best) out = std::min(out, misses);
  return out;
}

bool cp_pin_even(const void*, std::uint64_t key) { return key % 2 == 0; }
bool cp_pin_all(const void*, std::uint64_t) { return true; }
bool cp_pin_in_set(const void* ctx, std::uint64_t key) {
  return static_cast<const std::set<std::uint64_t>*>(ctx)->count(key) != 0;
}

}  // namespace

TEST_CASE("replacement policies: the table has lru, clock, s3fifo and arc, a typo gets 'did you mean'") {
  const std::vector<std::string> names = cp_policy_names();
  for (const char* n : {"lru", "clock", "s3fifo", "arc"})
    CHECK(std::find(names.begin(), names.end(), n) != names.end());
  try {
    make_replacement_policy("s3fifp", 10);
    FAIL("no exception");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find("did you mean 's3fifo'") != std::string::npos);
  }
  CHECK_THROWS_AS(simulate(cp_unit({1, 2}), "clok", 4), std::invalid_argument);
  CHECK_THROWS_AS(simulate(cp_unit({1, kNoKey}), "lru", 4), std::invalid_argument);
  CHECK_THROWS_AS(simulate(cp_unit({1}), "lru", kMaxPolicyCapacity + 1), std::invalid_argument);
  CHECK_THROWS_AS(belady_min(cp_unit({kNoKey}), 4), std::invalid_argument);
  CHECK_THROWS_AS(pfoo_lower(cp_unit({1}), kMaxPolicyCapacity + 1), std::invalid_argument);
}

TEST_CASE("replacement policies: the textbook reference string with 3 frames") {
  const std::vector<Access> seq = cp_unit(kCpTextbook);
  CHECK(cp_fifo_misses(kCpTextbook, 3) == 15);
  CHECK(belady_min(seq, 3).misses == 9);
  CHECK(belady_size(seq, 3).misses == 9);
  CHECK(simulate(seq, "lru", 3).misses == 12);
  // CLOCK (ring from the hand, subscript = reference bit; a key enters behind the hand, bit 0):
  //  7 0 1 miss [7₀ 0₀ 1₀]; 2 miss: 7 out [0₀ 1₀ 2₀]; 0 hit [0₁ 1₀ 2₀]; 3 miss: 0 cleared, 1 out
  //  [2₀ 0₀ 3₀]; 0 hit; 4 miss: 2 out [0₁ 3₀ 4₀]; 2 miss: 0 cleared, 3 out [4₀ 0₀ 2₀]; 3 miss:
  //  4 out [0₀ 2₀ 3₀]; 0 3 2 hit (all bits set); 1 miss: a full sweep clears them, 0 out
  //  [2₀ 3₀ 1₀]; 2 hit; 0 miss: 2 cleared, 3 out [1₀ 2₀ 0₀]; 1 hit; 7 miss: 1 cleared, 2 out
  //  [0₀ 1₀ 7₀]; 0 1 hit. Misses: 11.
  CHECK(simulate(seq, "clock", 3).misses == 11);
  // S3-FIFO at 3: S's share is 3/10 = 0, so S is evicted whenever it holds a key (M holds at most
  // 3, never more than its share); G holds 3 keys. Queues oldest first, key:freq.
  //  7 0 1 miss S=[7 0 1]; 2 miss: 7 to G; 0 hit (0:1); 3 miss: 0 (freq 1, not > 1) to G;
  //  0 miss, ghost: M=[0], 1 to G; 4 miss: 2 to G (G=[7 1 2]); 2 miss, ghost: M=[0 2], 3 to G;
  //  3 miss, ghost: M=[0 2 3], 4 to G (G=[7 1 4]); 0 3 2 hit (freq 1 each); 1 miss, ghost: M=[0 2 3 1],
  //  S empty so M: 0, 2, 3 go back to the head with freq 0, then 0 out; 2 hit (2:1); 0 miss (no
  //  ghost: M victims leave none): S=[0], M: 1 (freq 0) out; 1 miss: S=[0 1], 0 to G (G=[7 4 0]);
  //  7 miss, ghost: M=[2 3 7], 1 to G; 0 miss, ghost: M: 2 back (freq 0), 3 out; 1 miss, ghost:
  //  7 out. Misses: 15 (hits: 0, 3, 2, 2, 0... the 5 of requests 5, 11, 12, 13, 15).
  CHECK(simulate(seq, "s3fifo", 3).misses == 15);
  // ARC at c = 3 (Megiddo and Modha Fig. 4; lists LRU first):
  //  7 0 1 miss T1=[7 0 1]; 2 miss, IV.A with |T1| = c: 7 deleted, T1=[0 1 2]; 0 hit T2=[0];
  //  3 miss, IV.B: REPLACE (|T1| = 2 > p = 0): 1 to B1; 0 hit; 4 miss, IV.A: B1's 1 deleted,
  //  REPLACE: 2 to B1; 2 miss in B1: p = 1, REPLACE (|T1| = 2 > 1): 3 to B1, T2=[0 2];
  //  3 miss in B1: p = 2, REPLACE (|T1| = 1 <= 2): 0 to B2, T2=[2 3]; 0 miss in B2: p = 1,
  //  REPLACE with x in B2 and |T1| = p = 1: 4 to B1, T2=[2 3 0]; 3 2 hit; 1 miss, IV.B: REPLACE
  //  (|T1| = 0): 0 to B2, T1=[1]; 2 hit; 0 miss in B2: p = 0, REPLACE (|T1| = 1 > 0): 1 to B1;
  //  1 miss in B1: p = 1, REPLACE (|T1| = 0): 3 to B2; 7 miss, IV.B: 2 to B2; 0 1 hit.
  //  Misses: 13.
  CHECK(simulate(seq, "arc", 3).misses == 13);
  const OptLowerBound lb = pfoo_lower(seq, 3);
  CHECK(lb.misses <= 9);
  CHECK(lb.requests == seq.size());
}

TEST_CASE("replacement policies: S3-FIFO moves a key seen twice to M, ghosts fill M, M reinserts with freq - 1") {
  // Capacity 10: S's share 1, M's 9, G's 9. a a a makes a:2; b..j fill S; k: S's oldest a (freq
  // 2 > 1) moves to M, b goes to G (victim b). b, c, d: ghost hits enter M, each evicts S's oldest
  // into G (c, d, e); a hit (a:3). e..j: ghost hits into M, victims f..k from S; S is then empty
  // and M holds 10 > 9. k: ghost hit into M; M's share exceeded: a (freq 3) back to the head with
  // freq 2, b (freq 0) out.
  std::vector<std::uint64_t> keys;
  for (char c : std::string("aaabcdefghijkbcadefghijk")) keys.push_back(static_cast<std::uint64_t>(c));
  const std::vector<Access> seq = cp_unit(keys);
  const auto p = make_replacement_policy("s3fifo", 10);
  std::vector<std::uint64_t> evicted;
  const SimStats st = simulate(seq, *p, 10, &evicted);
  std::vector<std::uint64_t> want;
  for (char c : std::string("bcdefghijkb")) want.push_back(static_cast<std::uint64_t>(c));
  CHECK(evicted == want);
  CHECK(st.misses == 21);
  CHECK(st.hits == 3);
}

TEST_CASE("replacement policies: the simulator with lru equals LruCache hit for hit and eviction for eviction") {
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    const std::vector<Access> seq = cp_random(seed, 600, 64, true);
    for (std::uint64_t capacity : {0ull, 1ull, 5ull, 9ull, 17ull, 40ull, 120ull}) {
      std::vector<std::uint64_t> from_cache;
      LruCache<int> cache(capacity, [&](TileKey k, int&, std::uint64_t, LruRemoval r) {
        if (r == LruRemoval::kEvicted) from_cache.push_back(k.bits);
      });
      for (const Access& a : seq) {
        TileKey k;
        k.bits = a.key;
        if (!cache.get(k)) cache.insert(k, 0, a.size);
      }
      const auto lru = make_replacement_policy("lru", capacity);
      std::vector<std::uint64_t> from_sim;
      const SimStats st = simulate(seq, *lru, capacity, &from_sim);
      CAPTURE(seed);
      CAPTURE(capacity);
      CHECK(st.hits == cache.stats().hits);
      CHECK(st.misses == cache.stats().misses);
      CHECK(st.rejected == cache.stats().rejected);
      CHECK(st.evictions == cache.stats().evictions);
      CHECK(from_sim == from_cache);
    }
  }
}

TEST_CASE("replacement policies: MIN is the exhaustive optimum, PFOO-L is below it, Belady-Size above") {
  for (std::uint64_t seed = 1; seed <= 60; ++seed) {
    const std::vector<Access> unit = cp_random(seed, 12, 6, false);
    const std::vector<Access> sized = cp_random(seed + 1000, 12, 6, true);
    for (std::uint64_t frames : {1ull, 2ull, 3ull}) {
      CAPTURE(seed);
      CAPTURE(frames);
      CHECK(belady_min(unit, frames).misses == cp_exhaustive_opt(unit, frames, true));
      CHECK(belady_min_bypass(unit, frames).misses == cp_exhaustive_opt(unit, frames, false));  // optional admission
      CHECK(pfoo_lower(unit, frames).misses <= cp_exhaustive_opt(unit, frames, false));
    }
    for (std::uint64_t capacity : {4ull, 9ull, 15ull}) {
      CAPTURE(capacity);
      const std::uint64_t opt = cp_exhaustive_opt(sized, capacity, false);
      CHECK(pfoo_lower(sized, capacity).misses <= opt);
      CHECK(belady_size(sized, capacity).misses >= opt);
    }
  }
}

TEST_CASE("replacement policies: no policy misses less than MIN or PFOO-L, Belady-Size is MIN when sizes are equal") {
  const std::vector<std::string> names = cp_policy_names();
  for (std::uint64_t seed = 1; seed <= 30; ++seed) {
    const std::vector<Access> unit = cp_random(seed, 2000, 200, false);
    for (std::uint64_t frames : {1ull, 2ull, 7ull, 20ull, 64ull, 150ull}) {
      CAPTURE(seed);
      CAPTURE(frames);
      const SimStats opt = belady_min(unit, frames);
      const OptLowerBound lb = pfoo_lower(unit, frames);
      CHECK(lb.misses <= opt.misses);
      for (const std::string& name : names) {
        CAPTURE(name);
        CHECK(opt.misses <= simulate(unit, name, frames).misses);
      }
      // Every access weighing 3 at a capacity of 3 * frames + 2: MIN on `frames` frames.
      std::vector<Access> threes = unit;
      for (Access& a : threes) a.size = 3;
      const SimStats bs = belady_size(threes, 3 * frames + 2);
      CHECK(bs.misses == opt.misses);
      CHECK(bs.hits == opt.hits);
      CHECK(bs.evictions == opt.evictions);
    }
    const std::vector<Access> sized = cp_random(seed + 77, 2000, 200, true);
    for (std::uint64_t capacity : {5ull, 30ull, 100ull, 400ull}) {
      CAPTURE(capacity);
      const OptLowerBound lb = pfoo_lower(sized, capacity);
      CHECK(lb.misses <= belady_size(sized, capacity).misses);
      for (const std::string& name : names) {
        CAPTURE(name);
        const SimStats st = simulate(sized, name, capacity);
        CHECK(lb.misses <= st.misses);
        CHECK(lb.bytes_missed <= st.bytes_missed);
      }
    }
  }
}

TEST_CASE("replacement policies, each: evict() passes over pinned keys, returns kNoKey when all are pinned") {
  for (const std::string& name : cp_policy_names()) {
    CAPTURE(name);
    const auto p = make_replacement_policy(name, 10);
    for (std::uint64_t k = 0; k < 10; ++k) p->admit(k, 1);
    for (std::uint64_t k = 0; k < 10; k += 3) p->hit(k);
    CHECK(p->evict(Pinned{cp_pin_all, nullptr}) == kNoKey);
    CHECK(p->size() == 10);
    std::set<std::uint64_t> out;
    for (int i = 0; i < 5; ++i) {
      const std::uint64_t v = p->evict(Pinned{cp_pin_even, nullptr});
      CHECK(v % 2 == 1);
      CHECK(v < 10);
      out.insert(v);
    }
    CHECK(out.size() == 5);
    CHECK(p->evict(Pinned{cp_pin_even, nullptr}) == kNoKey);
    CHECK(p->size() == 5);
  }
  // Random operations with random pinned sets and sizes: a victim is always a cached, unpinned key.
  for (const std::string& name : cp_policy_names()) {
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
      CAPTURE(name);
      CAPTURE(seed);
      std::mt19937_64 rng(seed);
      const std::uint64_t capacity = 40;
      const auto p = make_replacement_policy(name, capacity);
      std::map<std::uint64_t, std::uint64_t> cached;  // key -> size
      std::uint64_t bytes = 0;
      for (int op = 0; op < 3000; ++op) {
        const std::uint64_t key = rng() % 60;
        if (cached.count(key)) {
          if (rng() % 8 == 0) {
            p->remove(key);
            bytes -= cached[key];
            cached.erase(key);
          } else {
            p->hit(key);
          }
          continue;
        }
        const std::uint64_t size = 1 + rng() % 6;
        std::set<std::uint64_t> pinned;
        for (const auto& [k, s] : cached)
          if (rng() % 3 == 0) pinned.insert(k);
        bool room = true;
        while (size > capacity - bytes) {
          const std::uint64_t v = p->evict(Pinned{cp_pin_in_set, &pinned});
          if (v == kNoKey) {
            room = false;
            break;
          }
          REQUIRE(cached.count(v) == 1);
          CHECK(pinned.count(v) == 0);
          bytes -= cached[v];
          cached.erase(v);
        }
        if (!room) continue;
        p->admit(key, size);
        cached[key] = size;
        bytes += size;
        CHECK(p->size() == cached.size());
      }
    }
  }
}

TEST_CASE("replacement policies, each: restore() brings a victim back as if it had never left") {
  for (const std::string& name : cp_policy_names()) {
    CAPTURE(name);
    const auto p = make_replacement_policy(name, 10);
    for (std::uint64_t k = 0; k < 10; ++k) p->admit(k, 1);
    const std::uint64_t v = p->evict({});
    REQUIRE(v != kNoKey);
    CHECK(p->size() == 9);
    p->restore(v, 1);
    CHECK(p->size() == 10);
    p->restore(v, 1);  // already cached: no change
    CHECK(p->size() == 10);
    // CLOCK, S3-FIFO and ARC put it back where it was: the next victim again. LRU's and
    // level_lru's restore is their admit (the interface's default): the most recent end.
    if (name != "lru" && name != "level_lru") CHECK(p->evict({}) == v);
    p->remove(v);
    CHECK(p->size() == 9);
  }
}

TEST_CASE("replacement policies, each: after set_capacity the owner evicts down to the new capacity") {
  for (const std::string& name : cp_policy_names()) {
    CAPTURE(name);
    const auto p = make_replacement_policy(name, 20);
    for (std::uint64_t k = 0; k < 20; ++k) p->admit(k, 1);
    for (std::uint64_t k = 0; k < 20; k += 2) p->hit(k);
    CHECK(p->size() == 20);
    p->set_capacity(6);
    std::set<std::uint64_t> out;
    while (p->size() > 6) {
      const std::uint64_t v = p->evict({});
      REQUIRE(v < 20);
      out.insert(v);
    }
    CHECK(out.size() == 14);
    // It keeps working at the new capacity: a fresh key is admitted, one key leaves.
    p->admit(100, 1);
    const std::uint64_t v = p->evict({});
    CHECK(v != 100);
    CHECK(out.count(v) == 0);
    CHECK(p->size() == 6);
  }
}

TEST_CASE("replacement policies, each: replays are deterministic") {
  const std::vector<Access> seq = cp_random(5, 5000, 300, true);
  for (const std::string& name : cp_policy_names()) {
    CAPTURE(name);
    std::vector<std::uint64_t> e1, e2;
    const auto p1 = make_replacement_policy(name, 200);
    const auto p2 = make_replacement_policy(name, 200);
    const SimStats a = simulate(seq, *p1, 200, &e1);
    const SimStats b = simulate(seq, *p2, 200, &e2);
    CHECK(a.hits == b.hits);
    CHECK(a.bytes_missed == b.bytes_missed);
    CHECK(e1 == e2);
    CHECK(a.requests == seq.size());
    CHECK(a.hits + a.misses == a.requests);
  }
  // A policy's first victim on a unit scan of 0..10 at capacity 10: its eviction order at work.
  const std::vector<Access> scan = cp_unit({0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
  for (const std::string& name : cp_policy_names()) {
    CAPTURE(name);
    const auto p = make_replacement_policy(name, 10);
    std::vector<std::uint64_t> e;
    simulate(scan, *p, 10, &e);
    CHECK(e == std::vector<std::uint64_t>{0});
  }
}

TEST_CASE("replacement policies, each: a double admit (a contract breach) leaves the policy whole") {
  for (const std::string& name : cp_policy_names()) {
    CAPTURE(name);
    const auto p = make_replacement_policy(name, 4);
    for (std::uint64_t k = 0; k < 4; ++k) p->admit(k, 1);
    p->admit(2, 1);
    CHECK(p->size() == 4);
    std::set<std::uint64_t> out;
    for (int i = 0; i < 4; ++i) out.insert(p->evict({}));
    CHECK(out == std::set<std::uint64_t>{0, 1, 2, 3});
    CHECK(p->evict({}) == kNoKey);
  }
}
