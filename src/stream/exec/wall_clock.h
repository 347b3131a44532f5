#pragma once
// The real clock: int64 nanosecond ticks of std::chrono::steady_clock since an epoch, the time
// base of the threaded executor's stage stamps and of real-clock frame pacing. restart() moves the
// epoch (the replay starts the clock at its first frame). Thread-safe: the epoch is atomic, so
// workers may stamp while the owner reads; restart() is meant for when nothing is in flight.
#include <atomic>
#include <chrono>
#include <cstdint>

#include "core/time.h"

namespace vtsim {

class WallClock {
 public:
  WallClock() { restart(); }
  void restart() { epoch_ns_.store(steady_ns(), std::memory_order_relaxed); }
  Ticks now() const { return steady_ns() - epoch_ns_.load(std::memory_order_relaxed); }
  // The steady_clock instant of tick t (for sleep_until).
  std::chrono::steady_clock::time_point at(Ticks t) const {
    return std::chrono::steady_clock::time_point(std::chrono::nanoseconds(epoch_ns_.load(std::memory_order_relaxed) + t));
  }

 private:
  static std::int64_t steady_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }
  std::atomic<std::int64_t> epoch_ns_{0};
};

}  // namespace vtsim
