#pragma once
// Cache simulation of an access sequence at listed capacities, policy by policy, as libCacheSim's
// `cachesim` does (docs/cache.md, "Cache simulation on access files"): what `vtsim cachesim`
// prints. Every registered replacement policy (replacement_policies(), through the offline
// simulator, simulate.h) and the offline bounds of belady.h run on the same sequence.
//
// Capacities: a comma-separated list, each item one of
//   <n><unit>  bytes: B, KiB, MiB, GiB, TiB (powers of 1024) or KB, MB, GB, TB (powers of 1000),
//              n a decimal integer or with a fraction (0.5GiB); the result rounded down to bytes
//   <n>        an object count: every request weighs 1 (libCacheSim's --ignore-obj-size)
//   0.<digits> a fraction of the footprint (the bytes of the distinct keys, or their number)
// Bytes and counts cannot be mixed; fractions take the list's unit (bytes when the sequence has
// sizes and nothing else says). Errors name the item.
//
// Thread-safety: pure functions over their arguments.
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cache/policy/access.h"
#include "cache/policy/simulate.h"

namespace vtsim {

enum class CapacityUnit { kObjects, kBytes };

struct CapacityItem {
  std::string token;       // as the user typed it (trimmed)
  std::uint64_t value = 0; // bytes or objects (0 for a fraction until resolved)
  double fraction = 0;     // > 0: a fraction of the footprint
};

struct CapacityList {
  CapacityUnit unit = CapacityUnit::kBytes;
  bool unit_given = false;  // false: fractions only (the caller picks the unit)
  std::vector<CapacityItem> items;
};

// Throws InputError(where, "... 'item' ...") for an empty list or item, an unknown unit, a value
// of 0 or above 2^62, a fraction outside (0, 1], or bytes mixed with counts.
CapacityList parse_capacity_list(std::string_view text, const std::string& where);

// The footprint of `accesses` in `unit`: distinct keys, or the sum of each key's last size.
std::uint64_t access_footprint(std::span<const Access> accesses, CapacityUnit unit);

// Fractions resolved against the footprint (at least 1). Throws InputError(where, ...) for a
// resolved capacity of 0.
void resolve_capacities(CapacityList& list, std::uint64_t footprint, const std::string& where);

// Policies cachesim runs: the registry's names, then the offline ones:
//   belady         furthest next use, every miss admitted (unit sizes: Belady's MIN; bytes:
//                  Belady-Size, belady_size)
//   belady_reused  the same, a key never requested again not admitted (libCacheSim's Belady)
//   pfoo_lower     PFOO-L, a lower bound on every policy's misses (not a policy)
std::vector<std::string> cachesim_policy_names();
// Throws InputError(where, "unknown policy ... (one of: ...; did you mean ...)").
void check_cachesim_policy(std::string_view name, const std::string& where);

// One (policy, capacity) result. With kBytes, stats.bytes_missed is the missed requests' bytes
// and bytes_requested all requests' bytes; with kObjects both count requests (every one weighs 1,
// as in libCacheSim with --ignore-obj-size). pfoo_lower fills requests, misses and bytes_missed.
struct CacheSimResult {
  SimStats stats;
  std::uint64_t bytes_requested = 0;
};

// Runs `policy` at `capacity` over `accesses`, every request weighing 1 (kObjects) or its size
// (kBytes). Throws std::invalid_argument as simulate, InputError for an unknown policy.
CacheSimResult cachesim_run(std::span<const Access> accesses, std::string_view policy, std::uint64_t capacity,
                            CapacityUnit unit);

// What `vtsim cachesim` reports: the sequence's figures and one row per (policy, capacity).
struct CacheSimRow {
  std::string policy;
  std::string capacity_item;  // as typed
  std::uint64_t capacity = 0;
  CacheSimResult result;
};
struct CacheSimReport {
  std::string source, format;
  CapacityUnit unit = CapacityUnit::kBytes;
  std::uint64_t requests = 0, objects = 0, footprint = 0, zero_size_skipped = 0;
  std::vector<CacheSimRow> rows;
};

// The report as JSON (an object with the figures and "rows"; miss bytes only for bytes) and as
// CSV (policy,capacity_<unit>,requests,misses,miss_ratio[,bytes_requested,miss_bytes,byte_miss_ratio]).
// Ratios are printed as the shortest decimals that read back to the same double.
std::string cachesim_json(const CacheSimReport& report);
std::string cachesim_csv(const CacheSimReport& report);

}  // namespace vtsim
