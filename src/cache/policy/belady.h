#pragma once
// Offline bounds on what any replacement policy can achieve on a recorded access sequence
// (docs/cache.md, "Replacement policies and Belady's bound"). Same owner semantics as the
// simulator (simulate.h): a miss is admitted (demand fetch) unless larger than the capacity.
//
// belady_min   Belady's MIN (Belady, "A study of replacement algorithms for a virtual-storage
//              computer", IBM Systems Journal 1966): unit sizes, evict the cached key whose next
//              use is furthest in the future. Its misses are the minimum over every policy that
//              admits each missed key (Mattson et al. 1970 proved MIN optimal for demand paging),
//              so no registered policy misses less.
// belady_size  Belady-Size: with sizes, evict furthest-next-use keys until the missed key fits.
//              A feasible policy, so its misses are an UPPER bound on the optimum's (with sizes
//              the optimum is NP-hard: Berger, Beckmann and Harchol-Balter 2018 §2); it is not
//              optimal (it can evict a large object used soon rather than several small ones used
//              later). With equal sizes it is MIN on capacity / size frames.
// pfoo_lower   PFOO-L (Berger, Beckmann and Harchol-Balter, "Practical bounds on optimal caching
//              with variable object sizes", SIGMETRICS 2018, §4.2): a LOWER bound on the misses
//              of every policy, even one that may decline to admit. Request i of a key that is
//              requested again at j can hit at j only if the key stays cached over the j - i
//              steps between; that costs size * (j - i) of cache-time, and no schedule spends more
//              than capacity * n in total. Dropping the per-step constraint leaves a knapsack with
//              unit values, solved exactly by taking the cheapest intervals first: at least as
//              many hits as any feasible schedule. bytes_missed: the same relaxation for bytes
//              (value size, cost size * length: a fractional knapsack, shortest intervals first).
//
// What they do not model: the pipeline's timing feeds back into what is requested (a policy that
// keeps other tiles changes the next frames' requests, the bound replays one fixed sequence);
// the VT pool's pages in use this frame cannot be evicted (Pinned), and victims whose slots are
// still pending upload; prefetched or cancelled requests. A key's size is taken as constant.
//
// Complexity: O(n log n) time (next uses by one backward scan, a heap of next uses or a sort of
// the reuse intervals), O(n) memory. Thread-safety: pure functions.
#include <cstdint>
#include <span>
#include <vector>

#include "cache/policy/access.h"
#include "cache/policy/simulate.h"

namespace vtsim {

// MIN with `frames` cache slots; Access::size is ignored (bytes_missed counts 1 per miss).
SimStats belady_min(std::span<const Access> accesses, std::uint64_t frames);

// MIN when admission is optional: on a miss with every slot full, the missed key is one more
// candidate and is not admitted (`rejected`) when its next use is the furthest. The minimum over
// every policy that may decline a key (the VT pool declines when every slot is pinned), so it is
// at most belady_min and a lower bound for the live pool, whose pinning only adds constraints.
SimStats belady_min_bypass(std::span<const Access> accesses, std::uint64_t frames);

// Belady-Size at `capacity` in the owner's unit.
SimStats belady_size(std::span<const Access> accesses, std::uint64_t capacity);

// Belady-Size that admits a missed key only if it is requested again: libCacheSim's Belady
// (Belady.c: its insert and find treat next_access_vtime INT64_MAX so; docs/cache.md, "Cache
// simulation on access files"). With unit sizes belady_min_bypass <= belady_reused <= belady_min:
// MIN admits such a key and, when every cached key is requested again, evicts one of them for it;
// the bypass also declines keys that are requested again, later than every cached key.
// Same exceptions as belady_size.
SimStats belady_reused(std::span<const Access> accesses, std::uint64_t capacity);

struct OptLowerBound {
  std::uint64_t requests = 0;      // accesses replayed
  std::uint64_t misses = 0;        // no policy misses fewer requests at this capacity
  std::uint64_t bytes_missed = 0;  // no policy misses fewer bytes (owner's unit) at this capacity
};

// PFOO-L at `capacity` in the owner's unit.
OptLowerBound pfoo_lower(std::span<const Access> accesses, std::uint64_t capacity);

// next[i]: the index of the next request of accesses[i].key, or accesses.size() if none.
std::vector<std::uint64_t> next_uses(std::span<const Access> accesses);

}  // namespace vtsim
