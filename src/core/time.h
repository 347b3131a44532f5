#pragma once
// Simulated and measured time. One tick is one nanosecond, stored in a signed 64-bit integer:
// exact, totally ordered and bit-for-bit reproducible (a double clock would drift with the sum
// order), and good for 292 years of trace.
#include <cmath>
#include <cstdint>

namespace vtsim {

using Ticks = std::int64_t;
inline constexpr Ticks kTicksPerSecond = 1'000'000'000;
inline constexpr Ticks kTicksPerMs = 1'000'000;

// Seconds (double, from a trace) to ticks, rounded to the nearest nanosecond.
inline Ticks seconds_to_ticks(double s) { return static_cast<Ticks>(std::llround(s * 1e9)); }
inline double ticks_to_seconds(Ticks t) { return static_cast<double>(t) * 1e-9; }
inline double ticks_to_ms(Ticks t) { return static_cast<double>(t) * 1e-6; }

// Time to move `bytes` at `bytes_per_s`, rounded up to a whole tick (never zero for non-zero
// work on a finite link; zero when the link is unconstrained, bytes_per_s <= 0).
inline Ticks transfer_ticks(std::uint64_t bytes, double bytes_per_s) {
  if (bytes_per_s <= 0.0 || bytes == 0) return 0;
  return static_cast<Ticks>(std::ceil(static_cast<double>(bytes) * 1e9 / bytes_per_s));
}

}  // namespace vtsim
