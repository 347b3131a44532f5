#include "sim/run/popin_share.h"

namespace vtsim {

namespace {
bool same_frame(bool has_before, const ResidencyFingerprint& before, const ResidencyFingerprint& after, int num_levels,
                bool e_has_before, const ResidencyFingerprint& e_before, const ResidencyFingerprint& e_after, int e_num_levels) {
  return e_has_before == has_before && e_after == after && e_num_levels == num_levels && (!has_before || e_before == before);
}
}  // namespace

void PopinShare::begin_frame(const SpanBuffer* spans) {
  const std::lock_guard<std::mutex> lock(mu_);
  spans_ = spans;
  if (levels_.size() < kMaxEntries) levels_.resize(kMaxEntries);
  if (frames_.size() < kMaxEntries) frames_.resize(kMaxEntries);
  used_.store(0, std::memory_order_release);
  frames_used_.store(0, std::memory_order_release);
}

const PopinShare::Levels* PopinShare::find(const ResidencyFingerprint& fp, bool marking) {
  const std::size_t n = used_.load(std::memory_order_acquire);
  for (std::size_t i = 0; i < n; ++i)
    if (levels_[i].fp == fp && levels_[i].marking == marking) return &levels_[i];
  return nullptr;
}

void PopinShare::publish(const ResidencyFingerprint& fp, bool marking, const SpanLevels& levels,
                         const std::vector<std::uint64_t>& marks) {
  const std::lock_guard<std::mutex> lock(mu_);
  const std::size_t n = used_.load(std::memory_order_relaxed);
  if (n == kMaxEntries || find(fp, marking)) return;
  Levels& e = levels_[n];
  e.fp = fp;
  e.marking = marking;
  e.levels = levels;
  e.marks = marks;
  used_.store(n + 1, std::memory_order_release);
}

bool PopinShare::find_frame(bool has_before, const ResidencyFingerprint& before, const ResidencyFingerprint& after,
                            int num_levels, PopinFrame& out) {
  const std::size_t n = frames_used_.load(std::memory_order_acquire);
  for (std::size_t i = 0; i < n; ++i) {
    const FrameEntry& e = frames_[i];
    if (same_frame(has_before, before, after, num_levels, e.has_before, e.before, e.after, e.num_levels)) {
      out = e.frame;
      return true;
    }
  }
  return false;
}

void PopinShare::publish_frame(bool has_before, const ResidencyFingerprint& before, const ResidencyFingerprint& after,
                               int num_levels, const PopinFrame& f) {
  const std::lock_guard<std::mutex> lock(mu_);
  const std::size_t n = frames_used_.load(std::memory_order_relaxed);
  if (n == kMaxEntries) return;
  PopinFrame dummy;
  if (find_frame(has_before, before, after, num_levels, dummy)) return;
  frames_[n] = FrameEntry{has_before, has_before ? before : ResidencyFingerprint{}, after, num_levels, f};
  frames_used_.store(n + 1, std::memory_order_release);
}

}  // namespace vtsim
