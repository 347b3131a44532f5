#include "sim/run/popin.h"

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

void resident_levels(const SpanBuffer& sb, const IResidency& residency, SpanLevels& out) {
  const int n = residency.num_levels();
  if (n < 1 || n > 127) throw std::invalid_argument("resident_levels: num_levels must be in [1, 127]");
  if (n > sb.levels) throw std::invalid_argument("resident_levels: num_levels exceeds the spans' levels");
  const std::size_t ns = sb.spans.size();
  out.span.resize(ns);
  out.offset.resize(ns);
  out.sample.clear();
  residency.span_resident_levels(sb.spans.data(), ns, out.span.data());
  thread_local std::vector<ViewSample> expanded;
  for (std::size_t i = 0; i < ns; ++i) {
    const std::int8_t r = out.span[i];
    if (r >= 0) {
      if (r > n) throw std::invalid_argument("resident_levels: residency returned a level outside [0, num_levels]");
      continue;
    }
    if (r != -1) throw std::invalid_argument("resident_levels: residency returned a level outside [0, num_levels]");
    expanded.clear();
    expand_span(sb, sb.spans[i], expanded);
    out.offset[i] = static_cast<std::uint32_t>(out.sample.size());
    out.sample.resize(out.sample.size() + expanded.size());
    std::int8_t* dst = out.sample.data() + out.offset[i];
    residency.resident_levels(expanded.data(), expanded.size(), dst);
    for (std::size_t k = 0; k < expanded.size(); ++k)
      if (dst[k] < 0 || dst[k] > n)
        throw std::invalid_argument("resident_levels: residency returned a level outside [0, num_levels]");
  }
}

PopinFrame popin_stats(const SpanBuffer& sb, const SpanLevels& now, const SpanLevels* before, int num_levels) {
  if (num_levels < 1 || num_levels > 127) throw std::invalid_argument("popin_stats: num_levels must be in [1, 127]");
  if (num_levels > sb.levels) throw std::invalid_argument("popin_stats: num_levels exceeds the spans' levels");
  const std::size_t ns = sb.spans.size();
  if (now.span.size() != ns || now.offset.size() != ns)
    throw std::invalid_argument("popin_stats: levels_now does not match the spans");
  if (before && (before->span.size() != ns || before->offset.size() != ns))
    throw std::invalid_argument("popin_stats: levels_before does not match the spans");
  // Level of sample k of span i.
  const auto level_at = [](const SpanLevels& L, std::size_t i, std::uint32_t k) -> int {
    return L.span[i] >= 0 ? L.span[i] : L.sample[L.offset[i] + k];
  };
  PopinFrame f;
  std::uint64_t deficit_sum = 0;
  for (std::size_t i = 0; i < ns; ++i) {
    const ViewSpan& sp = sb.spans[i];
    const int d = sp.level < num_levels - 1 ? sp.level : num_levels - 1;
    f.samples += sp.count;
    if (now.span[i] >= 0 && (!before || before->span[i] >= 0)) {  // uniform: count the span at once
      const int deficit = now.span[i] - d;
      if (deficit >= 1) {
        f.blurry += sp.count;
        deficit_sum += static_cast<std::uint64_t>(deficit) * sp.count;
      }
      if (before && now.span[i] <= before->span[i] - 1) f.visible_pops += sp.count;
      continue;
    }
    if ((now.span[i] < 0 && now.offset[i] + sp.count > now.sample.size()) ||
        (before && before->span[i] < 0 && before->offset[i] + sp.count > before->sample.size()))
      throw std::invalid_argument("popin_stats: per-sample levels do not match the spans");
    for (std::uint32_t k = 0; k < sp.count; ++k) {
      const int r = level_at(now, i, k);
      const int deficit = r - d;
      if (deficit >= 1) {
        ++f.blurry;
        deficit_sum += static_cast<std::uint64_t>(deficit);
      }
      if (before && r <= level_at(*before, i, k) - 1) ++f.visible_pops;
    }
  }
  if (f.samples > 0) {
    f.blurry_fraction = static_cast<double>(f.blurry) / static_cast<double>(f.samples);
    f.mean_deficit = static_cast<double>(deficit_sum) / static_cast<double>(f.samples);
  }
  return f;
}

}  // namespace vtsim
