#pragma once
// Feedback rendering ahead of the frame loop (docs/architecture.md, "Render-ahead"). A frame's
// feedback is a function of the scene, the camera and the view parameters only — not of what is
// streamed — so worker threads can render the frames the loop will need while the loop runs the
// streaming system on earlier ones. The loop takes the buffers in frame order, and they are bit
// for bit what it would have rendered itself (IScene::render_spans is thread-safe and
// deterministic): simulated metrics do not depend on the thread count.
//
// Contract: one consumer thread calls next(); the workers render into a ring of threads + 2
// slots. Slot states (guarded by one mutex): free → rendering → ready → held (the consumer's
// current frame) → free again when the consumer takes the next frame. A worker renders job j into
// slot j mod slots once job j − slots is released, so at most slots − 1 frames are rendered ahead
// and memory is bounded (two span buffers a slot). The destructor stops the workers after their
// current render and joins them.
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "core/camera.h"
#include "core/view.h"
#include "core/view_spans.h"

namespace vtsim {

class IScene;

class RenderAhead {
 public:
  struct Buffers {
    SpanBuffer feedback;
    SpanBuffer popin;  // rendered only with a pop-in ViewParams
  };

  // Renders `jobs` frames, job j from camera(j) (called on the workers: thread-safe, pure), with
  // `threads` (>= 1) workers. `popin`: also render each with these params into Buffers::popin (a
  // separate pop-in divisor). block_shift and keep_samples are set on every buffer as the loop
  // would. `feedback_of` (optional, thread-safe and pure like `camera`): job j's feedback params
  // instead of `feedback` (view.feedback_sampling = sequence moves the sample per frame). Throws
  // std::invalid_argument for threads < 1.
  RenderAhead(const IScene& scene, std::size_t jobs, std::function<Camera(std::size_t)> camera,
              const ViewParams& feedback, const ViewParams* popin, int block_shift, bool keep_samples, int threads,
              std::function<ViewParams(std::size_t)> feedback_of = nullptr);
  ~RenderAhead();
  RenderAhead(const RenderAhead&) = delete;
  RenderAhead& operator=(const RenderAhead&) = delete;

  // The next job's buffers, in job order; blocks until they are rendered. They are the caller's
  // until the next call (no worker touches a held slot: it may complete them, materialise_samples),
  // which releases the slot and invalidates them. Rethrows what the render of this job threw.
  // Throws std::logic_error past the last job.
  Buffers& next();

  // Blocks until the first min(n, jobs, slots − 1) jobs are rendered (or failed), before the first
  // next(): with n = threads each worker has most likely paid its first render's one-off set-up
  // (the real clock's loop waits so before frame 0). Throws std::logic_error after next().
  void wait_rendered(std::size_t n);

  // Whether jobs started from now on also keep their per-sample buffers (SpanBuffer::keep_samples;
  // the constructor's value until called). A hint: the buffers' results are the same either way,
  // only where the samples are shaded changes — a worker, or the consumer's materialise_samples.
  void set_keep_samples(bool on);

  // The thread count `view.render_threads` resolves to: `setting` itself when >= 0, else (auto)
  // one worker per CPU the process may use (its affinity mask) up to 8, none on a single one.
  static int resolve_threads(int setting);
  // `threads` capped so that the ring's threads + 2 slots of `bytes_per_slot` (a frame's buffers
  // at their largest) stay within kRingBytes, but at least 1 when threads >= 1: at divisor 1 a
  // 1920×1080 frame can hold ~150 MB of samples and spans.
  static int cap_threads(int threads, std::uint64_t bytes_per_slot);
  static constexpr std::uint64_t kRingBytes = std::uint64_t{512} << 20;
  // A frame's buffers at their largest: every pixel a sample and a span, in each rendered buffer.
  static std::uint64_t slot_bytes(int width, int height, const ViewParams& feedback, const ViewParams* popin);

 private:
  enum class SlotState { free, rendering, ready, held };
  struct Slot {
    Buffers buf;
    SlotState state = SlotState::free;
    std::size_t job = 0;
    std::exception_ptr error;
  };
  void work();

  const IScene& scene_;
  const std::size_t jobs_;
  const std::function<Camera(std::size_t)> camera_;
  const ViewParams feedback_;
  const std::function<ViewParams(std::size_t)> feedback_of_;  // null: feedback_ for every job
  const ViewParams popin_;
  const bool has_popin_;
  std::vector<Slot> slots_;
  std::mutex mu_;
  std::condition_variable can_work_;   // a job became startable, or stop
  std::condition_variable job_ready_;  // a slot became ready
  std::size_t next_job_ = 0;           // next job a worker starts
  std::size_t taken_ = 0;              // jobs handed to the consumer
  bool stop_ = false;
  bool keep_samples_;                  // for jobs started from now on
  std::vector<std::thread> workers_;   // last member: started after the state above exists
};

}  // namespace vtsim
