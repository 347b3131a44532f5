#pragma once
// Miss-ratio curves of LRU (docs/cache.md, "Miss-ratio curves"): the miss ratio of an LRU cache
// of every capacity from one pass over an access sequence.
//
// Exact: Mattson, Gecsei, Slutz, Traiger, "Evaluation techniques for storage hierarchies" (IBM
// Systems Journal 1970): LRU is a stack algorithm, so an access hits in a cache of capacity C iff
// its stack distance is at most C. The stack distance of a re-access is the total size of the
// distinct keys requested since the key's previous access, itself included (unit sizes: their
// number). Computed as in Bennett & Kruskal (1975) with prefix sums over access positions (a
// Fenwick tree over blocks of 64 positions beside the weights): each key's latest position holds
// its size, a re-access sums the positions from its previous one on and moves its size to the
// new position. O(n log K) time for n accesses of K distinct keys (positions are renumbered in
// order when they run out, so there are at most 4K + 1024), O(K) memory plus the histogram
// (pages: O(K); bytes: 8 bytes per re-access, sorted).
//
// Equality with the project's LruCache (cache/lru_cache.h) replaying the sequence as
// `get(key)` hit, else `insert(key, size)`: misses_at(C) equals the replay's misses for every
// C >= max_size when each key keeps one size. Below max_size the replay rejects oversized entries
// (which then neither enter nor evict) and LRU with rejection is no stack algorithm (its misses
// need not even fall as C grows); there misses_at(C) is an upper bound on the replay's misses.
// A re-access whose size differs from the key's previous one is counted as a miss at every
// capacity (the cached copy is stale) and charged the new size from then on; `size_changes`
// counts them, and with any the equality above is not guaranteed. Tests: tests/test_mrc.cpp.
//
// SHARDS: Waldspurger, Park, Garthwaite, Ahmad, "Efficient MRC Construction with SHARDS" (FAST
// 2015). Fixed-rate spatial sampling: a key is sampled iff mix64(key) mod P < T, rate R = T/P;
// the exact algorithm runs on the sampled accesses and their distances are scaled by 1/R.
// SHARDS_adj (§4.2 of the paper) adds the difference between the expected (R n) and the actual
// number of sampled accesses to the first bucket of the histogram.
//
// Thread-safety: the functions are pure; the structs are values.
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "cache/policy/access.h"

namespace vtsim {

enum class MrcUnit : std::uint8_t {
  kPages,  // every access weighs 1 (the VT page pool); Access::size is ignored
  kBytes,  // an access weighs Access::size bytes (the RAM tier)
};
const char* mrc_unit_name(MrcUnit u);  // "pages" | "bytes"

// The stack-distance histogram of one sequence.
struct StackHistogram {
  MrcUnit unit = MrcUnit::kPages;
  std::vector<std::uint64_t> distance;   // ascending, distinct finite stack distances (pages or bytes)
  std::vector<std::uint64_t> hits_upto;  // hits_upto[i]: re-accesses with a distance <= distance[i]
  std::uint64_t accesses = 0;            // accesses in the sequence
  std::uint64_t cold = 0;                // first accesses of a key: a miss at every capacity
  std::uint64_t size_changes = 0;        // re-accesses with another size: a miss at every capacity
  std::uint64_t keys = 0;                // distinct keys
  std::uint64_t footprint = 0;           // pages: keys; bytes: sum of each key's latest size
  std::uint64_t max_size = 0;            // pages: 1 (0 when empty); bytes: the largest access size

  // Accesses with a distance <= capacity (pages or bytes). O(log distinct distances).
  std::uint64_t hits_at(std::uint64_t capacity) const;
  // The misses of an LRU cache of that capacity (see the header comment for the exact domain).
  std::uint64_t misses_at(std::uint64_t capacity) const { return accesses - hits_at(capacity); }
  // misses_at / accesses (1 for an empty sequence).
  double miss_ratio_at(std::uint64_t capacity) const;
};

// Throws std::invalid_argument for the key kNoKey (~0, never a key; i_replacement.h).
StackHistogram lru_stack_histogram(std::span<const Access> accesses, MrcUnit unit);

// P of the SHARDS sampling condition mix64(key) mod P < T: 2^24, the paper's modulus (fine enough
// for rates down to 6e-8).
inline constexpr std::uint64_t kShardsModulus = std::uint64_t{1} << 24;

struct ShardsHistogram {
  StackHistogram sampled;  // of the sampled accesses, distances scaled by 1/rate (rounded)
  std::uint64_t threshold = 0;  // T: a key is sampled iff mix64(key) mod kShardsModulus < T
  double rate = 0;              // R = T / kShardsModulus (the requested rate, rounded to a multiple of 1/P)
  std::uint64_t accesses = 0;   // n: all accesses, sampled or not
  double expected = 0;          // R n: the sampled accesses expected
  bool adjusted = true;         // SHARDS_adj applied

  // Estimated miss ratio of an LRU cache of that capacity, in [0, 1].
  double miss_ratio_at(std::uint64_t capacity) const;
};

// rate in (0, 1] with rate * 2^24 >= 0.5 (T rounds to at least 1); otherwise std::invalid_argument.
// adjust: SHARDS_adj. At rate 1 every key is sampled and the result equals the exact histogram.
ShardsHistogram shards_histogram(std::span<const Access> accesses, MrcUnit unit, double rate, bool adjust = true);

// The knee of a curve: Kneedle (Satopää, Albrecht, Irwin, Raghavan, "Finding a 'Kneedle' in a
// Haystack", ICDCS workshops 2011) offline: x and y normalised to [0, 1], a falling y flipped to
// rising, and the knee is the point where the difference curve y_n - x_n is largest (the point
// farthest above the chord from the first to the last point). Kneedle's sensitivity S only
// delays online detection and does not move that maximum. No knee when the largest difference is
// not above 1e-9 (a straight or concave curve; rounding) or with fewer than 3 points.
struct Knee {
  bool found = false;
  std::size_t index = 0;       // find_knee: the point; in a MissRatioCurve: the point nearest the knee
  std::uint64_t capacity = 0;  // pages or bytes
  double miss_ratio = 0;
};
Knee find_knee(std::span<const std::uint64_t> capacity, std::span<const double> miss_ratio);

// A curve sampled at `points` capacities, for output.
struct MissRatioCurve {
  MrcUnit unit = MrcUnit::kPages;
  double shards_rate = 0;                // 0: exact; else the SHARDS rate used
  std::vector<std::uint64_t> capacity;   // ascending: 0, F/(points-1), ..., F (F: the footprint), pages or bytes
  std::vector<double> miss_ratio;        // at each capacity, in [0, 1]
  Knee knee;                             // on 1025 capacities (see sample_curve)
  std::uint64_t accesses = 0;
  std::uint64_t keys = 0;          // distinct keys (SHARDS: sampled keys / rate, rounded)
  std::uint64_t footprint = 0;     // pages or bytes (SHARDS: estimated)
  std::uint64_t max_size = 0;      // pages: 1; bytes: the largest access (SHARDS: among those sampled)
  std::uint64_t size_changes = 0;  // exact only (SHARDS: 0)
};

// points >= 2 (else std::invalid_argument). Capacities are evenly spaced from 0 to the footprint
// (beyond it the ratio no longer changes: only cold misses remain). The knee is found on 1025
// such capacities whatever `points` is, so the output's resolution does not move it.
MissRatioCurve sample_curve(const StackHistogram& h, std::size_t points);
MissRatioCurve sample_curve(const ShardsHistogram& h, std::size_t points);

// What `vtsim mrc` computes: the exact curve (shards_rate == 0) or SHARDS_adj at that rate.
struct MrcOptions {
  MrcUnit unit = MrcUnit::kPages;
  double shards_rate = 0;  // 0: exact; else in (0, 1]
  std::size_t points = 33; // sampled capacities: 32 intervals
};
MissRatioCurve miss_ratio_curve(std::span<const Access> accesses, const MrcOptions& options);

}  // namespace vtsim
