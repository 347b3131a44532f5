// Miss-ratio curves (src/cache/policy/mrc.h), side by side in one run on the same accesses:
//  (i)  the exact LRU curve in one pass (Mattson 1970 stack distances) against 8 full LruCache
//       replays at 8 sizes; target >= 20x, and the curve must equal the 8 replays' misses;
//  (ii) SHARDS_adj at 1% against the exact curve: target >= 10x, max |miss-ratio error| <= 0.005.
// Input: SYNTHETIC until the replay's access recorder exists: a sliding working set with Zipf
// reuse, 100 page accesses a frame for 36,000 frames (a 10-minute 60 Hz replay's pool sequence
// is a few million accesses). docs/cache.md, "Miss-ratio curves", carries the figures.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "cache/lru_cache.h"
#include "cache/policy/access.h"
#include "cache/policy/mrc.h"
#include "core/tile_key.h"
#include "harness.h"

namespace {

using vtsim::Access;
using vtsim::MrcUnit;
namespace vb = vtsim::bench;

// Page keys of a camera moving over a texture: frame f requests `per_frame` pages of a window of
// `window` keys starting at f * drift, by Zipf(0.9) rank (rank 0 the window's newest key, ranks
// scattered over the window by a fixed stride). Deterministic (splitmix64 over a counter).
std::vector<Access> sliding_zipf(std::size_t frames, std::size_t per_frame, std::uint64_t window, std::uint64_t drift) {
  std::vector<double> cdf(window);
  double sum = 0;
  for (std::uint64_t r = 0; r < window; ++r) cdf[r] = sum += 1.0 / std::pow(static_cast<double>(r + 1), 0.9);
  std::uint64_t state = 12345;
  std::vector<Access> seq;
  seq.reserve(frames * per_frame);
  for (std::size_t f = 0; f < frames; ++f)
    for (std::size_t i = 0; i < per_frame; ++i) {
      const double u = static_cast<double>(vtsim::mix64(state += 0x9E3779B97F4A7C15ULL) >> 11) * 0x1p-53;
      const auto r = static_cast<std::uint64_t>(std::lower_bound(cdf.begin(), cdf.end(), u * sum) - cdf.begin());
      seq.push_back({f * drift + (std::min(r, window - 1) * 7919) % window, 1});
    }
  return seq;
}

std::uint64_t replay_misses(const std::vector<Access>& seq, std::uint64_t capacity) {
  vtsim::LruCache<std::uint32_t> c(capacity);
  c.reserve(static_cast<std::size_t>(capacity));
  for (const Access& a : seq) {
    vtsim::TileKey k;
    k.bits = a.key;
    if (c.get(k) == nullptr) c.insert(k, 0, 1);
  }
  return c.stats().misses;
}

}  // namespace

int main(int argc, char** argv) {
  vb::Harness h("mrc", argc, argv, 5, 3);
  const std::size_t frames = h.pick<std::size_t>(36000, 6000), per_frame = 100;
  const std::uint64_t window = 20000, drift = 2;
  const std::vector<Access> seq = sliding_zipf(frames, per_frame, window, drift);
  h.param("input", "SYNTHETIC sliding working set with Zipf(0.9) reuse (no recorded replay yet)");
  h.param("accesses", seq.size());
  h.param("frames", frames);
  h.param("accesses_per_frame", per_frame);
  h.param("window_pages", window);
  h.param("drift_pages_per_frame", drift);
  fmt::print("input: SYNTHETIC pool sequence (sliding window of {} pages, drift {}/frame, Zipf 0.9), {} frames x {} = {} "
             "accesses\n",
             window, drift, frames, per_frame, seq.size());

  // (i) one pass against 8 replays.
  std::vector<std::uint64_t> sizes;
  for (std::uint64_t k = 1; k <= 8; ++k) sizes.push_back(k * window / 4);  // 1/4 .. 2 windows
  vtsim::StackHistogram exact;
  std::vector<std::uint64_t> replayed(sizes.size());
  h.compare({.name = "exact_vs_8_replays", .metric = vb::Metric::kMsPerRep, .work = 1,
             .params = {{"sizes_pages", sizes}}, .target_ratio = 20},
            {"mrc_one_pass", {}, [&] { exact = vtsim::lru_stack_histogram(seq, MrcUnit::kPages); }},
            {"lru_cache_x8", {}, [&] {
               for (std::size_t i = 0; i < sizes.size(); ++i) replayed[i] = replay_misses(seq, sizes[i]);
             }});
  bool equal = true;
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    const bool same = exact.misses_at(sizes[i]) == replayed[i];
    equal = equal && same;
    fmt::print("  size {:>6} pages: curve {} misses, replay {} misses{}\n", sizes[i], exact.misses_at(sizes[i]), replayed[i],
               same ? "" : "  MISMATCH");
  }
  fmt::print("exact curve == 8 LruCache replays: {}\n", equal ? "yes" : "NO");
  h.param("exact_equals_replays", equal);
  h.param("keys", exact.keys);

  // (ii) SHARDS_adj 1% against the exact curve.
  vtsim::ShardsHistogram s1;
  h.compare({.name = "shards1_vs_exact", .metric = vb::Metric::kMsPerRep, .work = 1, .params = {{"rate", 0.01}},
             .target_ratio = 10},
            {"shards_adj_1pct", {}, [&] { s1 = vtsim::shards_histogram(seq, MrcUnit::kPages, 0.01); }},
            {"exact", {}, [&] { exact = vtsim::lru_stack_histogram(seq, MrcUnit::kPages); }});
  const vtsim::ShardsHistogram s1_raw = vtsim::shards_histogram(seq, MrcUnit::kPages, 0.01, false);
  const vtsim::MissRatioCurve curve = vtsim::sample_curve(exact, 201);
  double err = 0, err_raw = 0, err_at = 0, err_sum = 0;
  for (std::size_t i = 0; i < curve.capacity.size(); ++i) {
    const double e = std::fabs(s1.miss_ratio_at(curve.capacity[i]) - curve.miss_ratio[i]);
    err_sum += e;
    if (e > err) err = e, err_at = static_cast<double>(curve.capacity[i]);
    err_raw = std::max(err_raw, std::fabs(s1_raw.miss_ratio_at(curve.capacity[i]) - curve.miss_ratio[i]));
  }
  const double err_mean = err_sum / static_cast<double>(curve.capacity.size());
  fmt::print("SHARDS_adj 1%: max |miss-ratio error| {:.5f} (at {:.0f} pages; target <= 0.005: {}), mean {:.5f}, over 201 "
             "sizes 0..{} pages; unadjusted max {:.5f}; {} of {} accesses sampled ({:.0f} expected), {} sampled keys\n",
             err, err_at, err <= 0.005 ? "met" : "MISSED", err_mean, curve.footprint, err_raw, s1.sampled.accesses, seq.size(),
             s1.expected, s1.sampled.keys);
  fmt::print("knee (exact): {} pages, miss ratio {:.4f}; SHARDS_adj 1%: {} pages, {:.4f}\n", curve.knee.capacity,
             curve.knee.miss_ratio, vtsim::sample_curve(s1, 201).knee.capacity, vtsim::sample_curve(s1, 201).knee.miss_ratio);
  h.param("shards1_max_abs_error", err);
  h.param("shards1_mean_abs_error", err_mean);
  h.param("shards1_unadjusted_max_abs_error", err_raw);
  h.param("shards1_error_target", 0.005);
  const int rc = h.finish();
  return equal ? rc : 1;
}
