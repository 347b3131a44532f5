// libFuzzer entry of one target, chosen at compile time (VTSIM_FUZZ_TARGET, tests/fuzz/CMakeLists.txt).
#include <cstdio>
#include <cstdlib>

#include "fuzz_targets.h"

#ifndef VTSIM_FUZZ_TARGET
#error "VTSIM_FUZZ_TARGET must name a target"
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const vtsim::fuzz::Target* const target = [] {
    const vtsim::fuzz::Target* t = vtsim::fuzz::find_target(VTSIM_FUZZ_TARGET);
    if (t == nullptr) {
      std::fprintf(stderr, "no fuzz target '%s'\n", VTSIM_FUZZ_TARGET);
      std::abort();
    }
    return t;
  }();
  target->run(data, size);
  return 0;
}
