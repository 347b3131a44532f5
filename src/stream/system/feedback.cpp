#include "stream/system/feedback.h"

#include <algorithm>
#include <bit>
#include <climits>
#include <stdexcept>
#include <string>

#include "core/view_spans.h"

namespace vtsim {

namespace {

constexpr std::uint64_t kEmpty = ~std::uint64_t{0};  // layer 15: never a key of ours (layer 0)

// Open-addressing table from key bits to an index into `out`; entries are cleared after each call
// by walking `out`, so the table never needs a full reset.
struct Table {
  std::vector<std::uint64_t> keys;
  std::vector<std::uint32_t> slot_index;
  std::uint64_t mask = 0;
  void reset_to(std::size_t cap) {
    keys.assign(cap, kEmpty);
    slot_index.assign(cap, 0);
    mask = cap - 1;
  }
};

}  // namespace

namespace {

void check_aggregate_args(int tile_size_texels, int num_levels) {
  if (tile_size_texels < 1 || tile_size_texels > (1 << 24))
    throw std::invalid_argument("aggregate_feedback: tile size must be in [1, 2^24] texels");
  if (num_levels < 1 || num_levels > 64) throw std::invalid_argument("aggregate_feedback: num_levels must be in [1, 64]");
}

// Tile key of a level-0 texel at a level, with aggregate_feedback's checks.
std::uint64_t tile_key(std::int64_t u, std::int64_t v, int level, std::int64_t ts, bool pow2, int tile_shift) {
  if (u < 0 || v < 0)
    throw std::invalid_argument("aggregate_feedback: sample texel (" + std::to_string(u) + ", " + std::to_string(v) +
                                ") is negative");
  const std::int64_t lu = u >> level, lv = v >> level;
  const std::int64_t tx = pow2 ? lu >> tile_shift : lu / ts, ty = pow2 ? lv >> tile_shift : lv / ts;
  if (!TileKey::fits(0, static_cast<std::uint32_t>(level), tx, ty))
    throw std::invalid_argument("aggregate_feedback: tile (" + std::to_string(tx) + ", " + std::to_string(ty) +
                                ") does not fit a TileKey");
  return TileKey(0, static_cast<std::uint32_t>(level), tx, ty).bits;
}

// Merges (key, count) runs into `out` through the per-thread hash table; finish() clears the
// table's used slots and sorts `out` by key.
class TileCounter {
 public:
  explicit TileCounter(std::vector<TileUse>& out) : out_(out), table_(table()) {
    out_.clear();
    if (table_.keys.empty()) table_.reset_to(1024);
  }
  void add(std::uint64_t key, std::uint32_t count) {
    std::uint64_t h = mix64(key) & table_.mask;
    while (true) {
      const std::uint64_t k = table_.keys[h];
      if (k == key) {
        out_[table_.slot_index[h]].samples += count;
        return;
      }
      if (k == kEmpty) break;
      h = (h + 1) & table_.mask;
    }
    table_.keys[h] = key;
    table_.slot_index[h] = static_cast<std::uint32_t>(out_.size());
    TileUse tu;
    tu.key.bits = key;
    tu.samples = count;
    out_.push_back(tu);
    if (out_.size() * 2 > table_.keys.size()) {  // keep the load factor <= 1/2
      table_.reset_to(table_.keys.size() * 2);
      for (std::size_t i = 0; i < out_.size(); ++i) {
        std::uint64_t g = mix64(out_[i].key.bits) & table_.mask;
        while (table_.keys[g] != kEmpty) g = (g + 1) & table_.mask;
        table_.keys[g] = out_[i].key.bits;
        table_.slot_index[g] = static_cast<std::uint32_t>(i);
      }
    }
  }
  void finish() {
    for (const TileUse& t : out_) {  // clear the used slots for the next call
      std::uint64_t h = mix64(t.key.bits) & table_.mask;
      while (table_.keys[h] != t.key.bits) h = (h + 1) & table_.mask;
      table_.keys[h] = kEmpty;
    }
    std::sort(out_.begin(), out_.end(), [](const TileUse& a, const TileUse& b) { return a.key < b.key; });
  }

 private:
  static Table& table() {
    thread_local Table t;
    return t;
  }
  std::vector<TileUse>& out_;
  Table& table_;
};

}  // namespace

void aggregate_feedback(const ViewBuffer& vb, int tile_size_texels, int num_levels, std::vector<TileUse>& out) {
  check_aggregate_args(tile_size_texels, num_levels);
  TileCounter counter(out);
  const bool pow2 = std::has_single_bit(static_cast<unsigned>(tile_size_texels));
  const int tile_shift = std::countr_zero(static_cast<unsigned>(tile_size_texels));
  const int tile_bits = std::bit_width(static_cast<unsigned>(tile_size_texels));  // ts < 2^tile_bits
  const std::int64_t ts = tile_size_texels;

  std::uint64_t run_key = 0;
  std::uint32_t run_count = 0;
  // Cached tile of the current run: a sample with the same level inside [lo, hi) texels on both
  // axes extends it without recomputing the key.
  int run_level = -1;
  std::int64_t u_lo = 0, u_hi = 0, v_lo = 0, v_hi = 0;
  for (const ViewSample& s : vb.samples) {
    const int level = desired_level(s.lod, num_levels);
    if (level == run_level && s.u >= u_lo && s.u < u_hi && s.v >= v_lo && s.v < v_hi) {
      ++run_count;
      continue;
    }
    const std::uint64_t key = tile_key(s.u, s.v, level, ts, pow2, tile_shift);
    if (run_count > 0 && key == run_key) {
      ++run_count;
      continue;
    }
    if (run_count > 0) counter.add(run_key, run_count);
    run_key = key;
    run_count = 1;
    // Level-0 texel range of the tile, cached for the fast path; tx, ty < 2^27 (fits), so the
    // bounds stay below 2^62 when level + tile_bits < 35.
    if (level + tile_bits < 35) {
      const std::int64_t span = ts << level;
      TileKey k;
      k.bits = key;
      run_level = level;
      u_lo = k.x() * span;
      u_hi = u_lo + span;
      v_lo = k.y() * span;
      v_hi = v_lo + span;
    } else {
      run_level = -1;
    }
  }
  if (run_count > 0) counter.add(run_key, run_count);
  counter.finish();
}

void aggregate_feedback(const SpanBuffer& sb, int tile_size_texels, int num_levels, std::vector<TileUse>& out) {
  check_aggregate_args(tile_size_texels, num_levels);
  if (num_levels > sb.levels) throw std::invalid_argument("aggregate_feedback: num_levels exceeds the spans' levels");
  TileCounter counter(out);
  const bool pow2 = std::has_single_bit(static_cast<unsigned>(tile_size_texels));
  const int tile_shift = std::countr_zero(static_cast<unsigned>(tile_size_texels));
  const std::int64_t ts = tile_size_texels;
  thread_local std::vector<ViewSample> expanded;
  for (const ViewSpan& s : sb.spans) {
    const int level = s.level < num_levels - 1 ? s.level : num_levels - 1;
    // Power-of-two tiles: (u >> level) >> shift = u >> (level + shift) for u >= 0, so the corners'
    // tiles come from two shifts per axis; anything unusual takes tile_key's checked path below.
    if (pow2 && s.u_lo >= 0 && s.v_lo >= 0 && level + tile_shift < 63) {
      const int sh = level + tile_shift;
      const std::int64_t tx = s.u_lo >> sh, ty = s.v_lo >> sh;
      if (tx == (s.u_hi >> sh) && ty == (s.v_hi >> sh) && TileKey::fits(0, static_cast<std::uint32_t>(level), tx, ty)) {
        counter.add(TileKey(0, static_cast<std::uint32_t>(level), tx, ty).bits, s.count);
        continue;
      }
    }
    // The bounding box's corners in one tile: so is every sample (tiles are boxes).
    const std::uint64_t k0 = tile_key(s.u_lo, s.v_lo, level, ts, pow2, tile_shift);
    const std::uint64_t k1 = tile_key(s.u_hi, s.v_hi, level, ts, pow2, tile_shift);
    if (k0 == k1) {
      counter.add(k0, s.count);
      continue;
    }
    expanded.clear();  // a span across tiles (a tile size the spans' blocks do not nest in)
    expand_span(sb, s, expanded);
    for (const ViewSample& e : expanded) counter.add(tile_key(e.u, e.v, level, ts, pow2, tile_shift), 1);
  }
  counter.finish();
}

std::size_t add_level_seams(const ViewBuffer& vb, int tile_size_texels, int num_levels, std::vector<TileUse>& out) {
  if (tile_size_texels < 1 || tile_size_texels > (1 << 24))
    throw std::invalid_argument("add_level_seams: tile size must be in [1, 2^24] texels");
  if (num_levels < 1 || num_levels > 64) throw std::invalid_argument("add_level_seams: num_levels must be in [1, 64]");
  thread_local std::vector<std::uint64_t> cand;
  cand.clear();
  // Neighbouring pairs emit the same tiles again and again: a small direct-mapped filter of keys
  // already emitted keeps the candidate list (and its sort) short.
  std::uint64_t recent[256];
  std::fill(std::begin(recent), std::end(recent), kEmpty);
  const std::int64_t ts = tile_size_texels;
  const std::vector<ViewSample>& sm = vb.samples;
  const auto emit = [&](const ViewSample& s, int lo, int hi) {
    if (s.u < 0 || s.v < 0)
      throw std::invalid_argument("add_level_seams: sample texel (" + std::to_string(s.u) + ", " +
                                  std::to_string(s.v) + ") is negative");
    for (int l = lo; l <= hi; ++l) {
      const std::int64_t tx = (s.u >> l) / ts, ty = (s.v >> l) / ts;
      if (!TileKey::fits(0, static_cast<std::uint32_t>(l), tx, ty))
        throw std::invalid_argument("add_level_seams: tile does not fit a TileKey");
      const std::uint64_t key = TileKey(0, static_cast<std::uint32_t>(l), tx, ty).bits;
      std::uint64_t& slot = recent[mix64(key) & 255];
      if (slot == key) continue;
      slot = key;
      cand.push_back(key);
    }
  };
  thread_local std::vector<std::int8_t> lv;
  lv.resize(sm.size());
  for (std::size_t i = 0; i < sm.size(); ++i) lv[i] = static_cast<std::int8_t>(desired_level(sm[i].lod, num_levels));
  const auto pair = [&](std::size_t ia, std::size_t ib) {
    const int la = lv[ia], lb = lv[ib];
    if (la == lb) return;
    const ViewSample& a = sm[ia];
    const ViewSample& b = sm[ib];
    const int lo = la < lb ? la : lb, hi = la < lb ? lb : la;
    // Continuity: adjacent samples of one surface are divisor pixels apart, at most ~2^(hi+1)
    // texels per pixel; a factor 2 more margin.
    const std::int64_t du = a.u > b.u ? a.u - b.u : b.u - a.u, dv = a.v > b.v ? a.v - b.v : b.v - a.v;
    const int shift = hi + 2;
    const std::int64_t bound = shift < 48 ? (std::int64_t{vb.divisor} << shift) : INT64_MAX;
    if (du > bound || dv > bound) return;
    emit(a, lo, hi);
    emit(b, lo, hi);
  };
  const std::uint64_t w = static_cast<std::uint64_t>(vb.width > 0 ? vb.width : 1);
  std::uint64_t row_end = 0;  // first pixel of the row after sample i's
  std::size_t j = 0;          // first sample at or after the pixel below sample i
  for (std::size_t i = 0; i < sm.size(); ++i) {
    const std::uint64_t p = sm[i].pixel;
    if (p >= row_end) row_end = (p / w + 1) * w;  // one division per row
    if (i + 1 < sm.size() && sm[i + 1].pixel == p + 1 && p + 1 < row_end) pair(i, i + 1);
    const std::uint64_t below = p + w;
    while (j < sm.size() && sm[j].pixel < below) ++j;
    if (j < sm.size() && sm[j].pixel == below) pair(i, j);
  }
  if (cand.empty()) return 0;
  std::sort(cand.begin(), cand.end());
  cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
  // Merge: append the candidates out lacks, then restore the order.
  const std::size_t before = out.size();
  std::size_t k = 0;
  for (std::uint64_t key : cand) {
    while (k < before && out[k].key.bits < key) ++k;
    if (k < before && out[k].key.bits == key) continue;
    TileUse t;
    t.key.bits = key;
    t.samples = 0;
    out.push_back(t);
  }
  const std::size_t added = out.size() - before;
  if (added > 0)  // std::sort, not inplace_merge: no temporary buffer, so no allocation
    std::sort(out.begin(), out.end(), [](const TileUse& a, const TileUse& b) { return a.key < b.key; });
  return added;
}

}  // namespace vtsim
