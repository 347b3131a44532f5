// Access files (cache/policy/access_io.h), the input of `vtsim mrc`. An accepted file must write
// back to text that reads as the same log, and its exact and SHARDS curves must compute.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "cache/policy/access_io.h"
#include "cache/policy/mrc.h"
#include "fuzz_targets.h"

namespace vtsim::fuzz {

void access_file(const std::uint8_t* data, std::size_t size) {
  AccessLog log;
  bool accepted = false;
  expect_accept_or_reject("access_file", [&] {
    log = parse_accesses(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz");
    accepted = true;
  });
  if (!accepted) return;
  must_succeed("access_file", "round trip, curves", [&] {
    const AccessLog again = parse_accesses(format_accesses(log), "fuzz");
    bool same = again.frame_start == log.frame_start && again.accesses.size() == log.accesses.size();
    for (std::size_t i = 0; same && i < log.accesses.size(); ++i)
      same = again.accesses[i].key == log.accesses[i].key && again.accesses[i].size == log.accesses[i].size;
    if (!same) {
      std::fprintf(stderr, "vtsim fuzz access_file: the round trip changed the log\n");
      std::abort();
    }
    for (MrcUnit unit : {MrcUnit::kPages, MrcUnit::kBytes}) {
      const StackHistogram h = lru_stack_histogram(log.accesses, unit);
      if (h.accesses != log.accesses.size() || h.misses_at(0) != h.accesses) {
        std::fprintf(stderr, "vtsim fuzz access_file: a zero-size cache hit\n");
        std::abort();
      }
      (void)sample_curve(h, 9);
      (void)sample_curve(shards_histogram(log.accesses, unit, 0.5), 9);
    }
  });
}

}  // namespace vtsim::fuzz
