#include "cache/policy/belady.h"

#include <algorithm>
#include <queue>
#include <stdexcept>
#include <string>
#include <utility>

#include "cache/page_map.h"

namespace vtsim {

namespace {

__extension__ typedef unsigned __int128 BeladyU128;  // cache-time: capacity * n exceeds 64 bits

// Furthest-next-use eviction; unit: every access weighs 1 and capacity counts frames.
// bypass (unit only): a missed key whose next use is no sooner than every cached key's is not
// admitted (counted in `rejected`), the optimum when admission is optional.
// skip_never: a missed key never requested again is not admitted (libCacheSim's Belady.c); not
// counted in `rejected`.
SimStats belady_run(std::span<const Access> accesses, std::uint64_t capacity, bool unit, bool bypass = false,
                    bool skip_never = false) {
  if (capacity > kMaxPolicyCapacity)
    throw std::invalid_argument("belady: capacity " + std::to_string(capacity) + " is above 2^62");
  const std::vector<std::uint64_t> next = next_uses(accesses);
  struct Held {
    std::uint64_t next_use;
    std::uint64_t size;
  };
  PageMap<Held> held;
  // (next use, key), furthest first. A hit leaves its old entry behind: an entry is current when
  // it matches the key's held next use (next uses are distinct request indices, and n, "never",
  // is the next use of a key's last request only). Rebuilt when stale entries dominate.
  std::priority_queue<std::pair<std::uint64_t, std::uint64_t>> heap;
  std::uint64_t held_bytes = 0;
  SimStats st;
  for (std::size_t i = 0; i < accesses.size(); ++i) {
    const std::uint64_t key = accesses[i].key;
    const std::uint64_t size = unit ? 1 : accesses[i].size;
    if (key == kNoKey) throw std::invalid_argument("belady: access " + std::to_string(i) + " has the reserved key ~0");
    ++st.requests;
    if (Held* h = held.find(key)) {
      ++st.hits;
      h->next_use = next[i];
      heap.emplace(next[i], key);
      continue;
    }
    ++st.misses;
    st.bytes_missed += size;
    if (size > capacity) {
      ++st.rejected;
      continue;
    }
    if (skip_never && next[i] == accesses.size()) continue;
    if (bypass && size > capacity - held_bytes) {
      while (!heap.empty()) {  // drop stale entries so that the top is the furthest cached next use
        const Held* h = held.find(heap.top().second);
        if (h != nullptr && h->next_use == heap.top().first) break;
        heap.pop();
      }
      if (heap.empty() || next[i] >= heap.top().first) {
        ++st.rejected;
        continue;
      }
    }
    while (size > capacity - held_bytes) {
      const auto [nu, victim] = heap.top();
      heap.pop();
      const Held* h = held.find(victim);
      if (h == nullptr || h->next_use != nu) continue;  // stale
      held_bytes -= h->size;
      held.erase(victim);
      ++st.evictions;
    }
    held.put(key, {next[i], size});
    held_bytes += size;
    heap.emplace(next[i], key);
    if (heap.size() > 2 * held.size() + 1024) {
      std::vector<std::pair<std::uint64_t, std::uint64_t>> live;
      live.reserve(held.size());
      held.for_each([&](std::uint64_t k, const Held& v) { live.emplace_back(v.next_use, k); });
      heap = std::priority_queue<std::pair<std::uint64_t, std::uint64_t>>(std::less<std::pair<std::uint64_t, std::uint64_t>>(), std::move(live));
    }
  }
  return st;
}

}  // namespace

std::vector<std::uint64_t> next_uses(std::span<const Access> accesses) {
  const std::uint64_t n = accesses.size();
  std::vector<std::uint64_t> next(n, n);
  PageMap<std::uint64_t> later;  // key -> index of its next request seen so far (scanning back)
  for (std::uint64_t i = n; i-- > 0;) {
    const std::uint64_t key = accesses[i].key;
    if (key == kNoKey) throw std::invalid_argument("belady: access " + std::to_string(i) + " has the reserved key ~0");
    if (std::uint64_t* j = later.find(key)) {
      next[i] = *j;
      *j = i;
    } else {
      later.put(key, i);
    }
  }
  return next;
}

SimStats belady_min(std::span<const Access> accesses, std::uint64_t frames) { return belady_run(accesses, frames, true); }

SimStats belady_min_bypass(std::span<const Access> accesses, std::uint64_t frames) {
  return belady_run(accesses, frames, true, true);
}

SimStats belady_size(std::span<const Access> accesses, std::uint64_t capacity) {
  return belady_run(accesses, capacity, false);
}

SimStats belady_reused(std::span<const Access> accesses, std::uint64_t capacity) {
  return belady_run(accesses, capacity, false, false, true);
}

OptLowerBound pfoo_lower(std::span<const Access> accesses, std::uint64_t capacity) {
  if (capacity > kMaxPolicyCapacity)
    throw std::invalid_argument("pfoo_lower: capacity " + std::to_string(capacity) + " is above 2^62");
  const std::vector<std::uint64_t> next = next_uses(accesses);
  const std::uint64_t n = accesses.size();
  struct Interval {
    BeladyU128 cost;      // size * length: the cache-time a hit at the next request needs
    std::uint64_t length; // requests between the two
    std::uint64_t size;
  };
  std::vector<Interval> intervals;
  BeladyU128 total_bytes = 0;
  for (std::uint64_t i = 0; i < n; ++i) {
    total_bytes += accesses[i].size;
    if (next[i] < n && accesses[i].size <= capacity) {
      const std::uint64_t len = next[i] - i;
      intervals.push_back({static_cast<BeladyU128>(accesses[i].size) * len, len, accesses[i].size});
    }
  }
  const BeladyU128 budget = static_cast<BeladyU128>(capacity) * n;
  OptLowerBound b;
  b.requests = n;
  // Misses: unit values, the cheapest intervals first (ties in any order: same count).
  std::sort(intervals.begin(), intervals.end(), [](const Interval& x, const Interval& y) { return x.cost < y.cost; });
  BeladyU128 used = 0;
  std::uint64_t hits = 0;
  for (const Interval& iv : intervals) {
    if (iv.cost > budget - used) break;
    used += iv.cost;
    ++hits;
  }
  b.misses = n - hits;
  // Bytes: value size per cost size * length, so the shortest intervals first, the last one in
  // part (a fractional knapsack is solved exactly greedily, Dantzig 1957).
  std::sort(intervals.begin(), intervals.end(), [](const Interval& x, const Interval& y) { return x.length < y.length; });
  used = 0;
  BeladyU128 hit_bytes = 0;
  for (const Interval& iv : intervals) {
    if (iv.cost > budget - used) {
      hit_bytes += (budget - used) / iv.length;
      break;
    }
    used += iv.cost;
    hit_bytes += iv.size;
  }
  b.bytes_missed = static_cast<std::uint64_t>(total_bytes - hit_bytes);
  return b;
}

}  // namespace vtsim
