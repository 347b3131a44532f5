#include "sim/popin.h"

#include <stdexcept>

namespace vtsim {

void resident_levels(const ViewBuffer& vb, const IResidency& residency, std::vector<std::int8_t>& levels) {
  const int n = residency.num_levels();
  if (n < 1 || n > 127) throw std::invalid_argument("resident_levels: num_levels must be in [1, 127]");
  levels.resize(vb.samples.size());
  residency.resident_levels(vb.samples.data(), vb.samples.size(), levels.data());
  for (const std::int8_t r : levels)
    if (r < 0 || r > n) throw std::invalid_argument("resident_levels: residency returned a level outside [0, num_levels]");
}

PopinFrame popin_stats(const ViewBuffer& vb, const std::vector<std::int8_t>& levels_now,
                       const std::vector<std::int8_t>* levels_before, int num_levels) {
  if (num_levels < 1 || num_levels > 127) throw std::invalid_argument("popin_stats: num_levels must be in [1, 127]");
  const std::size_t n = vb.samples.size();
  if (levels_now.size() != n) throw std::invalid_argument("popin_stats: levels_now has the wrong size");
  if (levels_before && levels_before->size() != n)
    throw std::invalid_argument("popin_stats: levels_before has the wrong size");
  PopinFrame f;
  f.samples = n;
  std::uint64_t deficit_sum = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const int d = desired_level(vb.samples[i].lod, num_levels);
    const int deficit = levels_now[i] - d;
    if (deficit >= 1) {
      ++f.blurry;
      deficit_sum += static_cast<std::uint64_t>(deficit);
    }
  }
  if (levels_before)
    for (std::size_t i = 0; i < n; ++i)
      if (levels_now[i] <= (*levels_before)[i] - 1) ++f.visible_pops;
  if (n > 0) {
    f.blurry_fraction = static_cast<double>(f.blurry) / static_cast<double>(n);
    f.mean_deficit = static_cast<double>(deficit_sum) / static_cast<double>(n);
  }
  return f;
}

}  // namespace vtsim
