#pragma once
// Helpers shared by the view tests.
#include <atomic>
#include <bit>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>
#include <unistd.h>

#include "core/view.h"
#include "core/view_spans.h"

namespace vtsim::test {

// A fresh path in the temp directory (not created), unique per process and call.
inline std::string temp_path(const std::string& stem) {
  static std::atomic<int> counter{0};
  return (std::filesystem::temp_directory_path() /
          ("vtsim_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + "_" + stem))
      .string();
}

// Index of each buffer pixel's sample in vb.samples, or -1.
inline std::vector<int> sample_index(const ViewBuffer& vb) {
  std::vector<int> idx(static_cast<std::size_t>(vb.width) * static_cast<std::size_t>(vb.height), -1);
  for (std::size_t i = 0; i < vb.samples.size(); ++i) idx[vb.samples[i].pixel] = static_cast<int>(i);
  return idx;
}

inline std::uint64_t no_sample_total(const ViewCounters& c) {
  return c.sky + c.clipped + c.backfacing + c.outside_texture + c.untextured;
}

// Field-for-field equality (the lod bit for bit), for the span-against-sample exactness checks
// (test_view_spans.cpp, tests/fuzz/fuzz_obj.cpp).
inline bool same_sample(const ViewSample& a, const ViewSample& b) {
  return a.u == b.u && a.v == b.v && std::bit_cast<std::uint32_t>(a.lod) == std::bit_cast<std::uint32_t>(b.lod) &&
         a.pixel == b.pixel;
}

inline bool same_span(const ViewSpan& a, const ViewSpan& b) {
  return a.u_lo == b.u_lo && a.u_hi == b.u_hi && a.v_lo == b.v_lo && a.v_hi == b.v_hi && a.pixel == b.pixel &&
         a.count == b.count && a.first == b.first && a.level == b.level;
}

inline bool same_counters(const ViewCounters& a, const ViewCounters& b) {
  return a.sky == b.sky && a.clipped == b.clipped && a.backfacing == b.backfacing &&
         a.outside_texture == b.outside_texture && a.untextured == b.untextured;
}

}  // namespace vtsim::test
