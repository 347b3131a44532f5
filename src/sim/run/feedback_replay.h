#pragma once
// Feedback traces in replays (docs/feedback.md): record the feedback a camera replay's view
// requests (FeedbackRecorder, on ReplayEnv::on_view), and replay the streaming side from a
// recorded or converted feedback trace (run_feedback_replay): no scene, no render — each frame's
// tiles stand in for its feedback buffer (one single-texel span per tile, its sample count as the
// span's count), and the same SystemRun steps on them: pipeline, budgets, throttles, metrics.
// Pop-in is measured on the tiles the feedback asked for, weighted by their samples.
//
// Exactness (tested): for a virtual texture without feedback or sampling bias and with pop-in
// measured on the feedback buffer (view.popin_divisor 0), the replay from a trace recorded by
// `--record-feedback` gives the camera replay's summary on every metric (docs/feedback.md lists
// what differs: the trace's identity, the run's cost). Thread-safety: none.
#include <memory>
#include <string>
#include <vector>

#include "sim/run/frame_loop.h"
#include "sim/run/replay_config.h"
#include "sim/trace/feedback_trace.h"

namespace vtsim {

// Writes the feedback trace of a camera replay: set `env.on_view = std::ref(recorder)` (or a
// lambda calling it), run, then finish(). The header is written at the first frame (the feedback
// buffer's size is known then).
class FeedbackRecorder {
 public:
  FeedbackRecorder(std::string path, const ReplayConfig& cfg);
  void operator()(const FramePlan& plan, const FrameView& view);
  // Closes the file; returns the bytes written. Throws InputError on a write error.
  std::uint64_t finish();
  std::uint64_t frames() const { return w_ ? w_->frames() : 0; }

 private:
  std::string path_;
  TextureExtent texture_;
  std::uint32_t tile_size_;
  std::unique_ptr<FeedbackWriter> w_;
  FeedbackFrame frame_;
};

// Replays the streaming side of `cfg` from the feedback trace at `path`. Throws InputError (exit
// 2) for a bad file (FeedbackReader), a trace whose texture or tile size differs from the config's,
// or a run that needs per-sample LODs (a throttle policy that may bias the feedback, a page size
// that is not a power of two, run.system other than vt).
ReplayResult run_feedback_replay(const ReplayConfig& cfg, const std::string& path, const ReplayEnv& env = {});

}  // namespace vtsim
