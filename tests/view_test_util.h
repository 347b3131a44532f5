#pragma once
// Helpers shared by the view tests.
#include <atomic>
#include <filesystem>
#include <string>
#include <unistd.h>

#include "sim/view.h"

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

}  // namespace vtsim::test
