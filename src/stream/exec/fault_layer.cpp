#include "stream/exec/fault_layer.h"

namespace vtsim {

namespace {

// Uniform in [0, 1) from (seed, key, attempt, kind): independent draws per fault kind.
double draw(const FaultConfig& c, TileKey key, std::uint32_t attempt, std::uint64_t kind) {
  const std::uint64_t h = mix64(key.bits ^ mix64(c.seed ^ mix64((std::uint64_t{attempt} << 8) | kind)));
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

}  // namespace

FaultPlan plan_faults(const FaultConfig& c, TileKey key, std::uint32_t attempt) {
  FaultPlan p;
  if (c.io_error_rate > 0 && draw(c, key, attempt, 1) < c.io_error_rate) p.fault = Fault::io_error;
  else if (c.short_read_rate > 0 && draw(c, key, attempt, 2) < c.short_read_rate) p.fault = Fault::short_read;
  else if (c.checksum_rate > 0 && draw(c, key, attempt, 3) < c.checksum_rate) p.fault = Fault::checksum;
  if (c.slow_rate > 0 && c.slow_ms > 0 && draw(c, key, attempt, 4) < c.slow_rate)
    p.delay = static_cast<Ticks>(c.slow_ms * 1e6 + 0.5);
  return p;
}

FaultPlan FaultLayer::next(TileKey key) {
  if (!cfg_.any()) return {};
  std::lock_guard lock(m_);
  const FaultPlan p = plan_faults(cfg_, key, attempts_[key]++);
  switch (p.fault) {
    case Fault::io_error: ++counts_.io_error; break;
    case Fault::short_read: ++counts_.short_read; break;
    case Fault::checksum: ++counts_.checksum; break;
    default: break;
  }
  if (p.delay > 0) ++counts_.slow;
  return p;
}

FaultLayer::Counts FaultLayer::injected() const {
  std::lock_guard lock(m_);
  return counts_;
}

}  // namespace vtsim
