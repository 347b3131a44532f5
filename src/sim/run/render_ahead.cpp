#include "sim/run/render_ahead.h"

#include <sched.h>

#include <algorithm>
#include <stdexcept>

#include "sim/view/scene.h"

namespace vtsim {

RenderAhead::RenderAhead(const IScene& scene, std::size_t jobs, std::function<Camera(std::size_t)> camera,
                         const ViewParams& feedback, const ViewParams* popin, int block_shift, bool keep_samples,
                         int threads, std::function<ViewParams(std::size_t)> feedback_of)
    : scene_(scene),
      jobs_(jobs),
      camera_(std::move(camera)),
      feedback_(feedback),
      feedback_of_(std::move(feedback_of)),
      popin_(popin ? *popin : feedback),
      has_popin_(popin != nullptr),
      keep_samples_(keep_samples) {
  if (threads < 1) throw std::invalid_argument("render-ahead: threads must be at least 1");
  // threads + 2: every worker busy on a frame ahead while the consumer holds one and one is ready.
  slots_.resize(static_cast<std::size_t>(threads) + 2);
  for (Slot& s : slots_) s.buf.feedback.block_shift = s.buf.popin.block_shift = block_shift;
  workers_.reserve(static_cast<std::size_t>(threads));
  try {
    for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { work(); });
  } catch (...) {  // thread creation failed: stop the ones running
    {
      std::lock_guard<std::mutex> lk(mu_);
      stop_ = true;
    }
    can_work_.notify_all();
    for (std::thread& t : workers_) t.join();
    throw;
  }
}

RenderAhead::~RenderAhead() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    stop_ = true;
  }
  can_work_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void RenderAhead::work() {
  const std::size_t n = jobs_, nslots = slots_.size();
  std::unique_lock<std::mutex> lk(mu_);
  for (;;) {
    // Job j may start once its slot's previous job (j − nslots) is released: the consumer has
    // taken a later job, i.e. j − nslots + 1 < taken_.
    can_work_.wait(lk, [&] { return stop_ || (next_job_ < n && next_job_ + 1 < taken_ + nslots); });
    if (stop_ || next_job_ >= n) return;
    const std::size_t j = next_job_++;
    Slot& s = slots_[j % nslots];
    s.state = SlotState::rendering;
    s.job = j;
    s.error = nullptr;
    s.buf.feedback.keep_samples = s.buf.popin.keep_samples = keep_samples_;
    lk.unlock();
    std::exception_ptr error;
    try {
      const Camera cam = camera_(j);
      // Rendered into this worker's own buffer, then copied into the slot. The slot's memory was
      // last read by the consumer on another core, and the render's scattered writes into it paid
      // a cache-line transfer each: with one worker, user time was 3.2 s against 2.7 s rendering
      // in the loop (120 s town walk), and the copy brought the wall time from 3.07 to 2.73 s
      // (2 workers: 1.76 to 1.72 s). docs/architecture.md, "Render-ahead".
      thread_local SpanBuffer local;
      local.block_shift = s.buf.feedback.block_shift;
      local.keep_samples = s.buf.feedback.keep_samples;
      scene_.render_spans(cam, feedback_of_ ? feedback_of_(j) : feedback_, local);
      s.buf.feedback = local;
      if (has_popin_) scene_.render_spans(cam, popin_, s.buf.popin);
    } catch (...) {
      error = std::current_exception();
    }
    lk.lock();
    s.error = error;
    s.state = SlotState::ready;
    job_ready_.notify_one();  // one consumer
  }
}

RenderAhead::Buffers& RenderAhead::next() {
  std::unique_lock<std::mutex> lk(mu_);
  if (taken_ >= jobs_) throw std::logic_error("render-ahead: no job left");
  const std::size_t nslots = slots_.size();
  if (taken_ > 0) slots_[(taken_ - 1) % nslots].state = SlotState::free;
  const std::size_t j = taken_++;
  can_work_.notify_one();  // the released slot makes one more job startable: one worker
  Slot& s = slots_[j % nslots];
  job_ready_.wait(lk, [&] { return s.state == SlotState::ready && s.job == j; });
  s.state = SlotState::held;
  if (s.error) std::rethrow_exception(s.error);
  return s.buf;
}

void RenderAhead::wait_rendered(std::size_t n) {
  std::unique_lock<std::mutex> lk(mu_);
  if (taken_ != 0) throw std::logic_error("render-ahead: wait_rendered after next()");
  n = std::min({n, jobs_, slots_.size() - 1});  // jobs 0 .. slots − 2 may render before any is taken
  job_ready_.wait(lk, [&] {
    for (std::size_t j = 0; j < n; ++j)
      if (slots_[j].state != SlotState::ready || slots_[j].job != j) return false;
    return true;
  });
}

void RenderAhead::set_keep_samples(bool on) {
  std::lock_guard<std::mutex> lk(mu_);
  keep_samples_ = on;
}

int RenderAhead::resolve_threads(int setting) {
  if (setting >= 0) return setting;
  // The CPUs this process may run on (taskset, cpusets), not all the machine has.
  unsigned hw = std::thread::hardware_concurrency();
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0) hw = static_cast<unsigned>(CPU_COUNT(&set));
  return hw >= 2 ? static_cast<int>(std::min(hw, 8u)) : 0;
}

int RenderAhead::cap_threads(int threads, std::uint64_t bytes_per_slot) {
  if (threads < 1) return threads;
  const std::uint64_t slots = kRingBytes / std::max<std::uint64_t>(bytes_per_slot, 1);
  const std::uint64_t fit = slots > 3 ? slots - 2 : 1;
  return static_cast<int>(std::min<std::uint64_t>(static_cast<std::uint64_t>(threads), fit));
}

std::uint64_t RenderAhead::slot_bytes(int width, int height, const ViewParams& feedback, const ViewParams* popin) {
  const auto one = [&](const ViewParams& p) {
    const auto px = static_cast<std::uint64_t>(buffer_extent(width, p.divisor)) *
                    static_cast<std::uint64_t>(buffer_extent(height, p.divisor));
    return px * (sizeof(ViewSample) + sizeof(ViewSpan));
  };
  return one(feedback) + (popin ? one(*popin) : 0);
}

}  // namespace vtsim
