#pragma once
// Pop-in shared between the runs that step on the same spans (a lockstep sweep's runs,
// sim/sweep/lockstep.h). Runs whose residencies have equal fingerprints (IResidency::fingerprint)
// resolve the same spans to equal levels, so the first one resolves and publishes, the others
// copy: the levels, the slots the lookup marked sampled (replayed with IResidency::apply_marks),
// and the frame's PopinFrame. In a 16-config clipmap sweep over the plane walk the runs are in
// one of ~2 states a frame (docs/sweep.md, "Speed"). Exact: every run's summary is the same with
// and without a share (tests/test_sweep.cpp). At most kMaxEntries of each kind per begin_frame
// (beyond them the runs are mostly distinct, and storing would cost more than it saves).
// Thread-safe: publishers take a mutex and fill an entry before they count it (release); finders
// read the count (acquire) and scan without a lock. A published entry never changes or moves
// until begin_frame, which the caller makes sure no other thread overlaps (the lockstep calls it
// when it renders the spans into a buffer that no run holds).
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "cache/i_residency.h"
#include "core/view_spans.h"
#include "sim/run/popin.h"

namespace vtsim {

class PopinShare {
 public:
  static constexpr std::size_t kMaxEntries = 64;

  struct Levels {
    ResidencyFingerprint fp;
    bool marking = false;               // resolved with marking on: `marks` are its marks
    SpanLevels levels;
    std::vector<std::uint64_t> marks;   // distinct, in the lookup's order
  };
  // What a run took from shares and offered to them (SystemRun::popin_share_counts; kept per run,
  // not here, so that threads write no shared line per lookup).
  struct Counts {
    std::uint64_t levels_shared = 0, levels_resolved = 0;  // lookups copied, or resolved and published
    std::uint64_t frames_shared = 0;                       // PopinFrames copied
  };

  // New spans: the entries are forgotten (storage is reused). Not concurrent with anything.
  void begin_frame(const SpanBuffer* spans);
  const SpanBuffer* spans() const { return spans_; }

  // The published entry of (fp, marking), or null. Valid until begin_frame.
  const Levels* find(const ResidencyFingerprint& fp, bool marking);
  // Publishes a copy (unless another thread did first or the entries are full).
  void publish(const ResidencyFingerprint& fp, bool marking, const SpanLevels& levels, const std::vector<std::uint64_t>& marks);

  // The PopinFrame of (state before the commits, state after), `has_before` false when the run
  // committed nothing (no "before" pass): true and `out` when a run published it.
  bool find_frame(bool has_before, const ResidencyFingerprint& before, const ResidencyFingerprint& after, int num_levels,
                  PopinFrame& out);
  void publish_frame(bool has_before, const ResidencyFingerprint& before, const ResidencyFingerprint& after, int num_levels,
                     const PopinFrame& f);

 private:
  struct FrameEntry {
    bool has_before;
    ResidencyFingerprint before, after;
    int num_levels;
    PopinFrame frame;
  };
  std::mutex mu_;  // publishers
  const SpanBuffer* spans_ = nullptr;
  std::vector<Levels> levels_;       // [0, used_) published; kMaxEntries long, never moved
  std::atomic<std::size_t> used_{0};
  std::vector<FrameEntry> frames_;   // [0, frames_used_) published; kMaxEntries long
  std::atomic<std::size_t> frames_used_{0};
};

}  // namespace vtsim
