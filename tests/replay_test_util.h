#pragma once
// Comparing two replays' results in tests.
#include <doctest/doctest.h>

#include "sim/run/replay.h"

namespace vtsim::test {

// The same summary, but for the run's own cost ("run") and config (the callers compare runs whose
// configs differ in what must not change a result: render threads, pacing), and every per-frame
// row equal.
inline void check_same_results(ReplayResult a, ReplayResult b) {
  a.summary.erase("run");
  b.summary.erase("run");
  a.summary.erase("config");
  b.summary.erase("config");
  CHECK(a.summary.dump() == b.summary.dump());
  REQUIRE(a.metrics.frames().size() == b.metrics.frames().size());
  for (std::size_t i = 0; i < a.metrics.frames().size(); ++i) {
    CAPTURE(i);
    CHECK(a.metrics.frames()[i] == b.metrics.frames()[i]);
  }
}

}  // namespace vtsim::test
