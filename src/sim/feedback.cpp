#include "sim/feedback.h"

#include <algorithm>
#include <bit>
#include <stdexcept>
#include <string>

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

void aggregate_feedback(const ViewBuffer& vb, int tile_size_texels, int num_levels, std::vector<TileUse>& out) {
  if (tile_size_texels < 1 || tile_size_texels > (1 << 24))
    throw std::invalid_argument("aggregate_feedback: tile size must be in [1, 2^24] texels");
  if (num_levels < 1 || num_levels > 64) throw std::invalid_argument("aggregate_feedback: num_levels must be in [1, 64]");
  out.clear();
  thread_local Table table;
  if (table.keys.empty()) table.reset_to(1024);
  const bool pow2 = std::has_single_bit(static_cast<unsigned>(tile_size_texels));
  const int tile_shift = std::countr_zero(static_cast<unsigned>(tile_size_texels));
  const int tile_bits = std::bit_width(static_cast<unsigned>(tile_size_texels));  // ts < 2^tile_bits
  const std::int64_t ts = tile_size_texels;

  const auto add_run = [&](std::uint64_t key, std::uint32_t count) {
    std::uint64_t h = mix64(key) & table.mask;
    while (true) {
      const std::uint64_t k = table.keys[h];
      if (k == key) {
        out[table.slot_index[h]].samples += count;
        return;
      }
      if (k == kEmpty) break;
      h = (h + 1) & table.mask;
    }
    table.keys[h] = key;
    table.slot_index[h] = static_cast<std::uint32_t>(out.size());
    TileUse tu;
    tu.key.bits = key;
    tu.samples = count;
    out.push_back(tu);
    if (out.size() * 2 > table.keys.size()) {  // keep the load factor <= 1/2
      table.reset_to(table.keys.size() * 2);
      for (std::size_t i = 0; i < out.size(); ++i) {
        std::uint64_t g = mix64(out[i].key.bits) & table.mask;
        while (table.keys[g] != kEmpty) g = (g + 1) & table.mask;
        table.keys[g] = out[i].key.bits;
        table.slot_index[g] = static_cast<std::uint32_t>(i);
      }
    }
  };

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
    if (s.u < 0 || s.v < 0)
      throw std::invalid_argument("aggregate_feedback: sample texel (" + std::to_string(s.u) + ", " +
                                  std::to_string(s.v) + ") is negative");
    const std::int64_t lu = s.u >> level, lv = s.v >> level;
    const std::int64_t tx = pow2 ? lu >> tile_shift : lu / ts, ty = pow2 ? lv >> tile_shift : lv / ts;
    if (!TileKey::fits(0, static_cast<std::uint32_t>(level), tx, ty))
      throw std::invalid_argument("aggregate_feedback: tile (" + std::to_string(tx) + ", " + std::to_string(ty) +
                                  ") does not fit a TileKey");
    const std::uint64_t key = TileKey(0, static_cast<std::uint32_t>(level), tx, ty).bits;
    if (run_count > 0 && key == run_key) {
      ++run_count;
      continue;
    }
    if (run_count > 0) add_run(run_key, run_count);
    run_key = key;
    run_count = 1;
    // Level-0 texel range of the tile, cached for the fast path; tx, ty < 2^27 (fits), so the
    // bounds stay below 2^62 when level + tile_bits < 35.
    if (level + tile_bits < 35) {
      const std::int64_t span = ts << level;
      run_level = level;
      u_lo = tx * span;
      u_hi = u_lo + span;
      v_lo = ty * span;
      v_hi = v_lo + span;
    } else {
      run_level = -1;
    }
  }
  if (run_count > 0) add_run(run_key, run_count);

  for (const TileUse& t : out) {  // clear the used slots for the next call
    std::uint64_t h = mix64(t.key.bits) & table.mask;
    while (table.keys[h] != t.key.bits) h = (h + 1) & table.mask;
    table.keys[h] = kEmpty;
  }
  std::sort(out.begin(), out.end(), [](const TileUse& a, const TileUse& b) { return a.key < b.key; });
}

}  // namespace vtsim
