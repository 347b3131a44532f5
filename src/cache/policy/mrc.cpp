#include "cache/policy/mrc.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "core/tile_key.h"

namespace vtsim {

namespace {

// A size above 2^40 bytes (1 TiB) per access is refused: with it, footprints up to 2^23 such keys
// still sum within 2^63 (the check below), and no tile is remotely that large.
constexpr std::uint64_t kMrcMaxSize = std::uint64_t{1} << 40;
constexpr std::uint64_t kMrcMaxFootprint = std::uint64_t{1} << 63;

// Fenwick tree (Fenwick 1994) of per-block weights; sums are exact modulo 2^64, and the true
// sums stay below 2^63 (kMrcMaxFootprint), so subtracting by adding the two's complement is exact.
class MrcFenwick {
 public:
  void add(std::size_t i, std::uint64_t delta) {
    for (++i; i < t_.size(); i += i & (~i + 1)) t_[i] += delta;
  }
  // Sum of entries [0, i).
  std::uint64_t prefix(std::size_t i) const {
    std::uint64_t s = 0;
    for (; i > 0; i &= i - 1) s += t_[i];
    return s;
  }
  // Builds from per-entry weights in O(n).
  void build(const std::vector<std::uint64_t>& w) {
    t_.assign(w.size() + 1, 0);
    for (std::size_t i = 1; i < t_.size(); ++i) {
      t_[i] += w[i - 1];
      const std::size_t up = i + (i & (~i + 1));
      if (up < t_.size()) t_[up] += t_[i];
    }
  }

 private:
  std::vector<std::uint64_t> t_;  // 1-based
};

// Per-position weights with prefix sums: the weights themselves plus a Fenwick tree over blocks
// of kMrcBlock positions. A prefix sum walks the block tree (K / 16 bytes for K positions: it
// stays in cache where a tree over positions would not) and scans at most 63 weights of one
// block, contiguous. Measured 2x faster than a Fenwick tree over positions on the 3.6-million
// access sequence of bench/bench_mrc.cpp, whose time goes to cache misses.
class MrcPrefixSums {
 public:
  static constexpr std::size_t kMrcBlock = 64;
  std::size_t size() const { return w_.size(); }
  std::uint64_t weight(std::size_t i) const { return w_[i]; }
  void add(std::size_t i, std::uint64_t delta) {
    w_[i] += delta;
    blocks_.add(i / kMrcBlock, delta);
  }
  // Sum of positions [0, i).
  std::uint64_t prefix(std::size_t i) const {
    std::uint64_t s = blocks_.prefix(i / kMrcBlock);
    for (std::size_t j = i - i % kMrcBlock; j < i; ++j) s += w_[j];
    return s;
  }
  void build(std::vector<std::uint64_t> w) {
    w_ = std::move(w);
    std::vector<std::uint64_t> b((w_.size() + kMrcBlock - 1) / kMrcBlock, 0);
    for (std::size_t i = 0; i < w_.size(); ++i) b[i / kMrcBlock] += w_[i];
    blocks_.build(b);
  }

 private:
  std::vector<std::uint64_t> w_;
  MrcFenwick blocks_;
};

// Spare positions beyond 4x the live keys: renumbering (O(positions)) then runs at most once per
// 1024 accesses on a small working set, and once per 3K + 1024 accesses with K keys.
constexpr std::size_t kMrcSpare = 1024;

// The one pass (Mattson 1970 with Bennett-Kruskal's tree), over the accesses `take` accepts.
// Distances go to `dense` (pages: index = distance) or `sparse` (bytes: one entry per re-access).
template <class Take>
StackHistogram mrc_pass(std::span<const Access> accesses, MrcUnit unit, Take take) {
  StackHistogram h;
  h.unit = unit;
  const bool bytes = unit == MrcUnit::kBytes;
  PageMap<std::uint64_t> where;  // key -> its latest position (which holds its size): 16-byte slots
  MrcPrefixSums tree;
  tree.build(std::vector<std::uint64_t>(kMrcSpare, 0));
  std::vector<std::uint64_t> key_at(kMrcSpare, kNoKey);  // position -> the key whose latest access it holds
  std::size_t next = 0;         // the next free position
  std::uint64_t live = 0;       // sum of the live weights (= the footprint)
  std::vector<std::uint64_t> dense;   // pages: dense[d] re-accesses at distance d
  std::vector<std::uint64_t> sparse;  // bytes: every finite distance
  for (const Access& a : accesses) {
    if (!take(a.key)) continue;
    if (a.key == kNoKey) throw std::invalid_argument("miss-ratio curve: the key ~0 is reserved (never a key)");
    const std::uint64_t w = bytes ? a.size : 1;
    if (w > kMrcMaxSize)
      throw std::invalid_argument("miss-ratio curve: access size " + std::to_string(w) + " is above 2^40 bytes");
    ++h.accesses;
    h.max_size = std::max(h.max_size, w);
    if (next == tree.size()) {
      // Renumber the live positions 0..K-1 in their order (one scan, no sort), in a tree with
      // room for 4K + spare: the next renumbering is 3K + spare accesses away.
      std::size_t live_keys = 0;
      for (std::size_t p = 0; p < next; ++p)
        if (key_at[p] != kNoKey) key_at[live_keys++] = key_at[p];
      std::vector<std::uint64_t> weight(4 * live_keys + kMrcSpare, 0);
      for (std::size_t p = 0; p < live_keys; ++p) {
        std::uint64_t* moved = where.find(key_at[p]);
        if (moved == nullptr) throw std::logic_error("miss-ratio curve: a live position's key is not in the map");
        weight[p] = tree.weight(*moved);
        *moved = p;
      }
      tree.build(std::move(weight));
      key_at.resize(tree.size());
      std::fill(key_at.begin() + static_cast<std::ptrdiff_t>(live_keys), key_at.end(), kNoKey);
      next = live_keys;
    }
    std::uint64_t* pos = where.find(a.key);
    if (pos == nullptr) {
      ++h.cold;
      ++h.keys;
      if (w > kMrcMaxFootprint - live)
        throw std::invalid_argument("miss-ratio curve: the keys' sizes sum above 2^63 bytes");
      live += w;
      tree.add(next, w);
      where.put(a.key, next);
      key_at[next++] = a.key;
      continue;
    }
    const std::uint64_t old = tree.weight(*pos);
    const std::uint64_t d = live - tree.prefix(*pos);  // sizes at positions >= the previous access
    tree.add(*pos, ~old + 1);                           // minus the old weight
    if (w != old) {
      ++h.size_changes;
      if (w > old && w - old > kMrcMaxFootprint - live)
        throw std::invalid_argument("miss-ratio curve: the keys' sizes sum above 2^63 bytes");
      live = live - old + w;
    } else if (bytes) {
      sparse.push_back(d);
    } else {
      if (d >= dense.size()) dense.resize(std::max<std::size_t>(d + 1, 2 * dense.size()), 0);
      ++dense[d];
    }
    tree.add(next, w);
    key_at[*pos] = kNoKey;
    key_at[next] = a.key;
    *pos = next++;
  }
  h.footprint = live;
  std::uint64_t run = 0;
  if (bytes) {
    std::sort(sparse.begin(), sparse.end());
    for (std::size_t i = 0; i < sparse.size(); ++i) {
      ++run;
      if (i + 1 == sparse.size() || sparse[i + 1] != sparse[i]) {
        h.distance.push_back(sparse[i]);
        h.hits_upto.push_back(run);
      }
    }
  } else {
    for (std::size_t d = 0; d < dense.size(); ++d) {
      if (dense[d] == 0) continue;
      run += dense[d];
      h.distance.push_back(d);
      h.hits_upto.push_back(run);
    }
  }
  return h;
}

// A largest difference below this is rounding on a straight line, not a knee.
constexpr double kMrcKneeNoise = 1e-9;

std::vector<std::uint64_t> mrc_even_capacities(std::uint64_t footprint, std::size_t points) {
  if (points < 2) throw std::invalid_argument("miss-ratio curve: at least 2 points");
  const std::uint64_t steps = points - 1, q = footprint / steps, r = footprint % steps;
  std::vector<std::uint64_t> c(points);
  for (std::uint64_t i = 0; i < points; ++i) c[i] = q * i + r * i / steps;  // r * i < steps^2: no overflow
  return c;
}

}  // namespace

const char* mrc_unit_name(MrcUnit u) { return u == MrcUnit::kBytes ? "bytes" : "pages"; }

std::uint64_t StackHistogram::hits_at(std::uint64_t capacity) const {
  const auto it = std::upper_bound(distance.begin(), distance.end(), capacity);
  return it == distance.begin() ? 0 : hits_upto[static_cast<std::size_t>(it - distance.begin()) - 1];
}

double StackHistogram::miss_ratio_at(std::uint64_t capacity) const {
  if (accesses == 0) return 1.0;
  return static_cast<double>(misses_at(capacity)) / static_cast<double>(accesses);
}

StackHistogram lru_stack_histogram(std::span<const Access> accesses, MrcUnit unit) {
  return mrc_pass(accesses, unit, [](std::uint64_t) { return true; });
}

double ShardsHistogram::miss_ratio_at(std::uint64_t capacity) const {
  const double n_s = static_cast<double>(sampled.accesses);
  double hits = static_cast<double>(sampled.hits_at(capacity));
  double total = n_s;
  if (adjusted) {
    // SHARDS_adj: the first bucket gains expected - actual sampled accesses.
    total = expected;
    if (!sampled.distance.empty() && capacity >= sampled.distance.front()) hits += expected - n_s;
  }
  if (!(total > 0)) return 1.0;
  return std::clamp((total - hits) / total, 0.0, 1.0);  // at rate 1: misses / accesses, as exact
}

ShardsHistogram shards_histogram(std::span<const Access> accesses, MrcUnit unit, double rate, bool adjust) {
  const double t = std::round(rate * static_cast<double>(kShardsModulus));
  if (!(rate > 0.0 && rate <= 1.0) || t < 1.0)
    throw std::invalid_argument("SHARDS rate " + std::to_string(rate) + " is outside (0, 1] (or below 2^-25)");
  ShardsHistogram s;
  s.threshold = static_cast<std::uint64_t>(t);
  s.rate = t / static_cast<double>(kShardsModulus);
  s.adjusted = adjust;
  s.accesses = accesses.size();
  s.expected = s.rate * static_cast<double>(s.accesses);
  const std::uint64_t threshold = s.threshold;
  s.sampled = mrc_pass(accesses, unit,
                       [threshold](std::uint64_t key) { return (mix64(key) & (kShardsModulus - 1)) < threshold; });
  if (threshold == kShardsModulus) return s;  // rate 1: exact, nothing to scale
  // Scale distances (and the footprint, a capacity) by 1/R; rounding may merge neighbours.
  auto scale = [&](std::uint64_t d) {
    const double x = std::round(static_cast<double>(d) / s.rate);
    return x >= 0x1p64 ? std::numeric_limits<std::uint64_t>::max() : static_cast<std::uint64_t>(x);
  };
  StackHistogram& h = s.sampled;
  std::vector<std::uint64_t> dist, upto;
  for (std::size_t i = 0; i < h.distance.size(); ++i) {
    const std::uint64_t d = scale(h.distance[i]);
    if (!dist.empty() && dist.back() == d) {
      upto.back() = h.hits_upto[i];
    } else {
      dist.push_back(d);
      upto.push_back(h.hits_upto[i]);
    }
  }
  h.distance = std::move(dist);
  h.hits_upto = std::move(upto);
  h.footprint = scale(h.footprint);
  return s;
}

Knee find_knee(std::span<const std::uint64_t> capacity, std::span<const double> miss_ratio) {
  Knee k;
  const std::size_t n = std::min(capacity.size(), miss_ratio.size());
  if (n < 3) return k;
  const double x0 = static_cast<double>(capacity.front()), x1 = static_cast<double>(capacity[n - 1]);
  const auto [lo, hi] = std::minmax_element(miss_ratio.begin(), miss_ratio.begin() + static_cast<std::ptrdiff_t>(n));
  const double ylo = *lo, yhi = *hi;
  if (!(x1 > x0) || !(yhi > ylo)) return k;
  double best = kMrcKneeNoise;
  for (std::size_t i = 0; i < n; ++i) {
    const double xn = (static_cast<double>(capacity[i]) - x0) / (x1 - x0);
    const double yn = (yhi - miss_ratio[i]) / (yhi - ylo);  // falling curve flipped to rising
    const double diff = yn - xn;
    if (diff > best) {
      best = diff;
      k.found = true;
      k.index = i;
    }
  }
  if (k.found) {
    k.capacity = capacity[k.index];
    k.miss_ratio = miss_ratio[k.index];
  }
  return k;
}

namespace {

// The knee on kMrcKneePoints even capacities from 0 to the footprint, whatever the output's
// resolution (a coarse grid would move it); index: the output capacity nearest to it.
constexpr std::size_t kMrcKneePoints = 1025;

template <class Histogram>
Knee mrc_fine_knee(const Histogram& h, const std::vector<std::uint64_t>& out) {
  const std::vector<std::uint64_t> fine = mrc_even_capacities(out.back(), kMrcKneePoints);
  std::vector<double> ratio;
  ratio.reserve(fine.size());
  for (std::uint64_t cap : fine) ratio.push_back(h.miss_ratio_at(cap));
  Knee k = find_knee(fine, ratio);
  if (!k.found) return k;
  k.index = 0;
  for (std::size_t i = 1; i < out.size(); ++i) {
    const auto dist = [&](std::uint64_t x) { return x > k.capacity ? x - k.capacity : k.capacity - x; };
    if (dist(out[i]) < dist(out[k.index])) k.index = i;
  }
  return k;
}

}  // namespace

MissRatioCurve sample_curve(const StackHistogram& h, std::size_t points) {
  MissRatioCurve c;
  c.unit = h.unit;
  c.capacity = mrc_even_capacities(h.footprint, points);
  for (std::uint64_t cap : c.capacity) c.miss_ratio.push_back(h.miss_ratio_at(cap));
  c.knee = mrc_fine_knee(h, c.capacity);
  c.accesses = h.accesses;
  c.keys = h.keys;
  c.footprint = h.footprint;
  c.max_size = h.max_size;
  c.size_changes = h.size_changes;
  return c;
}

MissRatioCurve sample_curve(const ShardsHistogram& h, std::size_t points) {
  MissRatioCurve c;
  c.unit = h.sampled.unit;
  c.shards_rate = h.rate;
  c.capacity = mrc_even_capacities(h.sampled.footprint, points);
  for (std::uint64_t cap : c.capacity) c.miss_ratio.push_back(h.miss_ratio_at(cap));
  c.knee = mrc_fine_knee(h, c.capacity);
  c.accesses = h.accesses;
  c.keys = static_cast<std::uint64_t>(std::round(static_cast<double>(h.sampled.keys) / h.rate));
  c.footprint = h.sampled.footprint;
  c.max_size = h.sampled.max_size;
  return c;
}

MissRatioCurve miss_ratio_curve(std::span<const Access> accesses, const MrcOptions& options) {
  if (options.shards_rate == 0) return sample_curve(lru_stack_histogram(accesses, options.unit), options.points);
  return sample_curve(shards_histogram(accesses, options.unit, options.shards_rate), options.points);
}

}  // namespace vtsim
