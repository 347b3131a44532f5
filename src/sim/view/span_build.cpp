#include "sim/view/span_build.h"

#include <cmath>

#include "sim/view/lod.h"
#include "core/view.h"

namespace vtsim::detail {

namespace {

constexpr std::uint64_t kCutCheckUlps = 256;

int level_of_q(double q, double bias, int levels) {
  return desired_level(static_cast<float>(0.5 * fast_log2(q) + bias), levels);
}

}  // namespace

const LevelCuts& level_cuts(double bias, int levels) {
  thread_local LevelCuts lc;
  if (lc.levels == levels && std::bit_cast<std::uint64_t>(lc.bias) == std::bit_cast<std::uint64_t>(bias)) return lc;
  lc.bias = bias;
  lc.levels = levels;
  lc.ok = true;
  const std::uint64_t lo_bits = std::bit_cast<std::uint64_t>(kMinFootprint2), hi_bits = std::bit_cast<std::uint64_t>(kMaxFootprint2);
  lc.cut[0] = -INFINITY;
  for (int k = 1; k <= levels; ++k) {
    if (level_of_q(kMinFootprint2, bias, levels) >= k) {
      lc.cut[k] = -INFINITY;
    } else if (level_of_q(kMaxFootprint2, bias, levels) < k) {
      lc.cut[k] = INFINITY;
    } else {  // level(lo) < k <= level(hi)
      std::uint64_t lo = lo_bits, hi = hi_bits;
      while (hi - lo > 1) {
        const std::uint64_t mid = lo + (hi - lo) / 2;
        if (level_of_q(std::bit_cast<double>(mid), bias, levels) >= k) hi = mid;
        else lo = mid;
      }
      lc.cut[k] = std::bit_cast<double>(hi);
      for (std::uint64_t d = 1; d <= kCutCheckUlps; ++d) {
        if (hi - d >= lo_bits && level_of_q(std::bit_cast<double>(hi - d), bias, levels) >= k) lc.ok = false;
        if (hi + d <= hi_bits && level_of_q(std::bit_cast<double>(hi + d), bias, levels) < k) lc.ok = false;
      }
    }
  }
  return lc;
}

}  // namespace vtsim::detail
