// Sweep specs (docs/sweep.md): a TOML file loaded as `vtsim sweep` loads it — traces, globs and
// generator lines, a grid, explicit configs, [tune] — every point expanded and validated. An
// accepted spec's generator lines must then generate (they were checked at load).
#include <string>

#include "fuzz_targets.h"
#include "sim/sweep/sweep_spec.h"
#include "sim/trace/trace_gen.h"

namespace vtsim::fuzz {

void sweep_spec(const std::uint8_t* data, std::size_t size) {
  SweepSpec spec;
  bool loaded = false;
  expect_accept_or_reject("sweep_spec", [&] {
    spec = load_sweep_spec(input_file(data, size, "toml"));
    loaded = true;
  });
  if (!loaded) return;
  for (const SweepTraceSource& s : spec.traces) {
    if (!s.generated) continue;
    // Generation itself may refuse a value out of range (as `vtsim trace gen` does), never crash;
    // a long trace is not generated here (a fuzzer's 1e6 s is 60 M poses).
    expect_accept_or_reject("sweep_spec", [&] {
      TraceGenParams p = parse_gen_line(s.text, "generate");
      if (p.duration_s * p.fps > 1e4) return;
      (void)generate_trace(p);
    });
  }
}

}  // namespace vtsim::fuzz
