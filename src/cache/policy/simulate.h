#pragma once
// The offline simulator: replays a recorded access sequence through a replacement policy at a
// capacity, with the RAM cache's owner semantics (docs/cache.md, "Replacement policies and
// Belady's bound"). A request hits when its key is cached (the policy's hit()); a miss admits the
// key (admit()), then evicts (evict(), the incoming key pinned) until the keys held fit the
// capacity, then charges the key; a key larger than the capacity is not admitted and counts as a
// miss (rejected). Admitting before evicting is LruCache::insert's order and the one in which
// ARC's REPLACE sees the missed key (policy_arc.cpp). With "lru" the result equals LruCache's, hit
// for hit and eviction for eviction (tests/test_cache_policy.cpp).
//
// Complexity: O(n) policy calls plus the evictions, two PageMap lookups per request (the held
// sizes and the policy's own index). Memory: the held keys' PageMap (2-4 slots of 16 bytes per
// key) and the policy's. Thread-safety: none shared; separate calls may run on separate threads.
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "cache/policy/access.h"
#include "cache/policy/i_replacement.h"

namespace vtsim {

struct SimStats {
  std::uint64_t requests = 0;      // accesses replayed
  std::uint64_t hits = 0;          // requests whose key was cached
  std::uint64_t misses = 0;        // requests = hits + misses (rejected included)
  std::uint64_t bytes_missed = 0;  // sizes of the missed requests, in the owner's unit
  std::uint64_t evictions = 0;     // keys evicted to make room
  std::uint64_t rejected = 0;      // misses larger than the capacity, never admitted
};

// Capacities above this are refused: 2 * capacity must not wrap (ARC bounds its directory by 2c).
inline constexpr std::uint64_t kMaxPolicyCapacity = std::uint64_t{1} << 62;

// The order of a miss. kAdmitFirst: admit the key, then evict with it pinned (LruCache::insert's
// order; ARC's REPLACE needs the missed key). kEvictFirst: evict until the key fits, then admit
// (libCacheSim's cache_get_base). LRU and FIFO choose the same victims either way; CLOCK does not:
// admitted first, the new key sits behind the hand ahead of the keys whose bits the sweep then
// clears, admitted after the sweep it comes after them (docs/cache.md, "Against libCacheSim").
enum class MissOrder { kAdmitFirst, kEvictFirst };

// Replays `accesses` through `policy` (fresh, or continuing from a previous replay's state: the
// held keys start empty, so pass a fresh policy) at `capacity` in the owner's unit. Appends the
// evicted keys in order to `evicted` when given. Throws std::invalid_argument for a key ~0
// (reserved, kNoKey) or a capacity above kMaxPolicyCapacity; std::logic_error if the policy
// returns kNoKey or a key it was not given while room is needed (a broken policy).
SimStats simulate(std::span<const Access> accesses, IReplacementPolicy& policy, std::uint64_t capacity,
                  std::vector<std::uint64_t>* evicted = nullptr, MissOrder order = MissOrder::kAdmitFirst);

// The VT pool's rules offline: accesses in frames (frame_start[f]: index of frame f's first
// access; begin_frame(f) is called as each starts; empty: each access is a frame), keys the current frame requests (anywhere in it)
// are pinned, and a miss that finds every cached key pinned is not admitted (counted in `rejected`,
// the pool's failed reservation). Fills are instant: no timing. Same exceptions as simulate.
SimStats simulate_frames(std::span<const Access> accesses, std::span<const std::uint64_t> frame_start,
                         IReplacementPolicy& policy, std::uint64_t capacity);

// The same through a fresh policy from the table (replacement_policies()); throws
// std::invalid_argument for an unknown name (with "did you mean").
SimStats simulate(std::span<const Access> accesses, std::string_view policy, std::uint64_t capacity);

}  // namespace vtsim
