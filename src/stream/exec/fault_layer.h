#pragma once
// Injected IO faults (docs/real-engine.md §4), the same in both clocks: a read of a tile may fail
// with EIO, come back short, come back with a corrupted payload (caught by the record checksum),
// or be slow. Each decision is a pure function of (seed, tile, attempt, kind) — a splitmix64 hash
// turned into a uniform number in [0, 1) — so a run is reproducible in the simulated clock and the
// real clock sees the same faults for the same tiles; a retry is a new attempt and may succeed.
//
// Precedence when several kinds fire on one attempt: io_error, then short_read, then checksum
// (one failure per read); slow adds its delay independently.
//
// Thread-safety: plan_faults is pure; FaultLayer counts attempts per tile under a mutex, so the
// IO pool's workers may share one. Memory: one counter per tile ever read (only when a fault rate
// is non-zero; otherwise nothing is stored).
#include <cstdint>
#include <mutex>
#include <unordered_map>

#include "core/tile_key.h"
#include "core/time.h"
#include "stream/exec/i_executor.h"

namespace vtsim {

struct FaultConfig {
  double io_error_rate = 0.0;    // probability a read fails with EIO (config io.fault_rate)
  std::uint64_t seed = 1;        // io.fault_seed
  double short_read_rate = 0.0;  // probability a read returns fewer bytes than the record (io.fault.short_read_rate)
  double checksum_rate = 0.0;    // probability the payload arrives corrupted (io.fault.checksum_rate)
  double slow_rate = 0.0;        // probability a read is slow (io.fault.slow_rate)
  double slow_ms = 0.0;          // extra service time of a slow read, ms (io.fault.slow_ms)

  bool any() const { return io_error_rate > 0 || short_read_rate > 0 || checksum_rate > 0 || (slow_rate > 0 && slow_ms > 0); }
};

struct FaultPlan {
  Fault fault = Fault::none;  // io_error, short_read or checksum: what this read will suffer
  Ticks delay = 0;            // extra service time (a slow request), ticks
};

// The faults of attempt `attempt` (0 = first read) of tile `key`.
FaultPlan plan_faults(const FaultConfig& c, TileKey key, std::uint32_t attempt);

class FaultLayer {
 public:
  explicit FaultLayer(const FaultConfig& c = {}) : cfg_(c) {}
  const FaultConfig& config() const { return cfg_; }
  bool active() const { return cfg_.any(); }

  // The plan of the next read of `key` (its attempts are counted here).
  FaultPlan next(TileKey key);

  struct Counts {
    std::uint64_t io_error = 0, short_read = 0, checksum = 0, slow = 0;  // injected so far
  };
  Counts injected() const;

 private:
  FaultConfig cfg_;
  mutable std::mutex m_;
  std::unordered_map<TileKey, std::uint32_t, TileKeyHash> attempts_;  // guarded by m_
  Counts counts_;                                                      // guarded by m_
};

}  // namespace vtsim
