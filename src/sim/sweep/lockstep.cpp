#include "sim/sweep/lockstep.h"

#include "sim/run/feedback_replay.h"
#include "sim/trace/feedback_trace.h"

#include <algorithm>
#include <bit>
#include <mutex>
#include <thread>
#include <memory>
#include <stdexcept>

#include "core/error.h"
#include "core/camera.h"
#include "core/view_spans.h"
#include "sim/view/scene.h"
#include "sim/run/frame_loop.h"
#include "stream/system/i_system.h"

namespace vtsim {

std::string view_key(const ReplayConfig& cfg) {
  std::string key;
  for (const auto& f : replay_config_table().fields()) {
    // view.feedback_latency delays what each run reads (SystemRun), not what is rendered.
    const bool view = f.key.rfind("view.", 0) == 0 && f.key != "view.render_threads" && f.key != "view.feedback_latency";
    const bool scene = f.key.rfind("scene.", 0) == 0;
    const bool texture = f.key == "texture.width" || f.key == "texture.height" || f.key == "texture.texels_per_m" ||
                         f.key == "texture.origin_x_m" || f.key == "texture.origin_y_m";
    if (view || scene || texture || f.key == "run.fps") key.append(f.key).append("=").append(f.get(cfg)).append("\n");
  }
  key += "block_shift=" + std::to_string(std::bit_width(static_cast<unsigned>(cfg.texture.tile_size)) - 1) + "\n";
  return key;
}

// ---- the shared view ring ----

namespace {

// Frames rendered once into a ring of slots and read by several consumers, each at its own pace
// and in frame order; the consumer that first needs a render renders it (no thread of its own:
// on 2 cores a third runnable thread only adds switches). Renders are claimed in order
// (next_claim_); a consumer waiting for a render another is doing renders a later one meanwhile
// if its slot is free.
// Roles: left alone, the consumers run neck and neck (one that falls behind copies the pop-in the
// other resolved and catches up), and at the same frame both resolve the same new states: over
// the 10-minute plane walk, 13,000-21,000 of a 16-config clipmap sweep's ~70,000 resolutions on
// two threads were such doubles (one thread: 54,783 in all). So the last consumer, the follower,
// renders one frame ahead each frame it takes while it is less than kFollowerLead renders behind
// the leader: the others lead and resolve each new state first, the follower renders and copies.
// A follower kFollowerLead behind stops rendering ahead and the leaders render for themselves, so
// the work stays balanced (docs/sweep.md "Speed").
// Slot state machine: holding render j - slots (ready) with refs -> 0 when every consumer moved
// past it: free for render j -> the claimer of j renders, sets refs = consumers and publishes
// ready = j (release). A consumer needing j that another claimed waits on the
// slot's `ready` (atomic wait). A render that throws publishes kFailed: its waiters throw.
class ViewRing {
 public:
  ViewRing(const ReplayConfig& cfg, const FramePlan& plan, const IScene& scene, int block_shift, bool keep_samples,
           int consumers)
      : plan_(plan), scene_(scene), vc_(cfg.view), vp_(view_params(cfg.view)), pp_(view_params(cfg.view)),
        separate_popin_(cfg.view.popin_divisor > 0 && cfg.view.popin_divisor != cfg.view.divisor),
        consumers_(consumers), slots_(static_cast<std::size_t>(consumers) + kSlack),
        held_(static_cast<std::size_t>(consumers), -1), next_(static_cast<std::size_t>(consumers)),
        views_(static_cast<std::size_t>(consumers)) {
    if (cfg.view.popin_divisor > 0) pp_.divisor = cfg.view.popin_divisor;
    for (Slot& s : slots_) {
      s.feedback.block_shift = s.popin.block_shift = block_shift;
      s.feedback.keep_samples = s.popin.keep_samples = keep_samples;
    }
  }
  ViewRing(const ViewRing&) = delete;
  ViewRing& operator=(const ViewRing&) = delete;

  // Consumer c's view of frame f (frames in order 0, 1, ...). Valid until its next call.
  const FrameView& frame(int c, int f) {
    const auto ci = static_cast<std::size_t>(c);
    FrameView& v = views_[ci];
    v.frame = f;
    v.pose = &plan_.trace.poses[static_cast<std::size_t>(f)];
    v.measured = plan_.measured(f);
    const std::size_t j = next_[ci].load(std::memory_order_relaxed);
    v.fresh = j < plan_.render_frames.size() && plan_.render_frames[j] == f;
    if (!v.fresh) return v;  // the last rendered buffers stand in
    release(c);
    if (c > 0 && c == consumers_ - 1 && j + kFollowerLead > lead()) render_ahead();
    Slot& s = slots_[j % slots_.size()];
    const auto jj = static_cast<std::int64_t>(j);
    std::size_t claim = j;
    if (next_claim_.load(std::memory_order_acquire) == j && next_claim_.compare_exchange_strong(claim, j + 1)) {
      render(j, s);
    } else {
      // Another consumer renders j: render a later frame meanwhile if its slot is free, else wait.
      for (std::int64_t r = s.ready.load(std::memory_order_acquire); r != jj; r = s.ready.load(std::memory_order_acquire)) {
        if (r == kFailed) throw std::runtime_error("the view's render failed: " + error_);
        if (!render_ahead()) s.ready.wait(r, std::memory_order_acquire);
      }
    }
    v.feedback = &s.feedback;
    v.popin = separate_popin_ ? &s.popin : &s.feedback;
    held_[ci] = jj;
    next_[ci].store(j + 1, std::memory_order_relaxed);
    return v;
  }
  // The pop-in share of the spans consumer c holds (after frame(c, ...)).
  PopinShare& share(int c) { return slots_[static_cast<std::size_t>(held_[static_cast<std::size_t>(c)]) % slots_.size()].share; }
  // Consumer c is done with the buffers it holds (after its last frame).
  void release(int c) {
    const auto ci = static_cast<std::size_t>(c);
    if (held_[ci] < 0) return;
    Slot& s = slots_[static_cast<std::size_t>(held_[ci]) % slots_.size()];
    held_[ci] = -1;
    if (s.refs.fetch_sub(1, std::memory_order_acq_rel) == 1) s.refs.notify_all();
  }

 private:
  struct Slot {
    SpanBuffer feedback, popin;
    PopinShare share;  // the runs' pop-in on these spans, shared across consumers
    std::atomic<int> refs{0};
    std::atomic<std::int64_t> ready{-1};  // the render the slot holds; kFailed: it threw
  };
  static constexpr std::int64_t kFailed = -2;
  // Renders the ring holds beyond one per consumer, so that consumers drift apart without
  // waiting for each other (each wait is a futex call, dear on a paravirtualised VM). A slot is
  // one feedback buffer (~0.1 MB of spans at divisor 8, ~0.5 MB more with samples).
  static constexpr std::size_t kSlack = 14;
  // How far behind the leader the follower still renders ahead: half the ring. 4 left 700-1,800
  // doubles; 8, 80-250 (10-minute walk, two threads); with no limit the follower rendered nearly
  // every frame, fell behind, and the leader waited for its renders.
  static constexpr std::size_t kFollowerLead = 8;

  // The render the furthest consumer but the follower takes next.
  std::size_t lead() const {
    std::size_t l = 0;
    for (std::size_t o = 0; o + 1 < next_.size(); ++o) l = std::max(l, next_[o].load(std::memory_order_relaxed));
    return l;
  }

  // Claims and renders the next unclaimed render if its slot is free now (never waits).
  bool render_ahead() {
    std::size_t n = next_claim_.load(std::memory_order_acquire);
    if (n >= plan_.render_frames.size()) return false;
    Slot& t = slots_[n % slots_.size()];
    if (!free_for(n, t) || !next_claim_.compare_exchange_strong(n, n + 1)) return false;
    render(n, t);
    return true;
  }

  // The slot's previous render (n - slots) is published and every consumer moved past it. Claims
  // are in order, so once true it stays true until render n is published.
  bool free_for(std::size_t n, const Slot& t) const {
    const std::int64_t prev = n >= slots_.size() ? static_cast<std::int64_t>(n - slots_.size()) : -1;
    return t.ready.load(std::memory_order_acquire) == prev && t.refs.load(std::memory_order_acquire) == 0;
  }

  // Render j (claimed) into its slot once the slot's previous render is published and every
  // consumer has moved past it.
  void render(std::size_t j, Slot& s) {
    const std::int64_t prev = j >= slots_.size() ? static_cast<std::int64_t>(j - slots_.size()) : -1;
    for (std::int64_t r = s.ready.load(std::memory_order_acquire); r != prev; r = s.ready.load(std::memory_order_acquire)) {
      if (r == kFailed) throw std::runtime_error("the view's render failed: " + error_);
      s.ready.wait(r, std::memory_order_acquire);
    }
    for (int r = s.refs.load(std::memory_order_acquire); r != 0; r = s.refs.load(std::memory_order_acquire))
      s.refs.wait(r, std::memory_order_acquire);
    try {
      const Pose& pose = plan_.trace.poses[static_cast<std::size_t>(plan_.render_frames[j])];
      const Camera cam = make_camera(pose, plan_.trace.image_width, plan_.trace.image_height);
      scene_.render_spans(cam, vc_.feedback_sampling == "middle" ? vp_ : feedback_params(vc_, plan_.render_frames[j]), s.feedback);
      if (separate_popin_) scene_.render_spans(cam, pp_, s.popin);
      s.share.begin_frame(separate_popin_ ? &s.popin : &s.feedback);
    } catch (const std::exception& e) {
      error_ = e.what();
      s.ready.store(kFailed, std::memory_order_release);
      s.ready.notify_all();
      throw;
    }
    s.refs.store(consumers_, std::memory_order_relaxed);
    s.ready.store(static_cast<std::int64_t>(j), std::memory_order_release);
    s.ready.notify_all();
  }

  const FramePlan& plan_;
  const IScene& scene_;
  const ViewConfig vc_;
  ViewParams vp_, pp_;
  bool separate_popin_;
  int consumers_;
  std::vector<Slot> slots_;
  std::vector<long long> held_;    // per consumer: the render it holds, -1 none
  std::vector<std::atomic<std::size_t>> next_;  // per consumer: the next render it takes (read by the follower)
  std::vector<FrameView> views_;   // per consumer
  std::atomic<std::size_t> next_claim_{0};
  std::string error_;              // written before a slot's ready = kFailed (release)
};

}  // namespace

// ---- run_lockstep ----

std::vector<LockstepResult> run_lockstep(const std::vector<const ReplayConfig*>& cfgs, const Trace& trace,
                                         const IScene& scene, int threads, std::atomic<std::uint64_t>* frames_done) {
  std::vector<LockstepResult> out(cfgs.size());
  if (cfgs.empty()) return out;
  const std::string key = view_key(*cfgs[0]);
  for (const ReplayConfig* c : cfgs)
    if (view_key(*c) != key) throw std::invalid_argument("run_lockstep: configs with different views");
  // A feedback trace (docs/feedback.md): nothing to render once, so each config replays it alone.
  if (!trace.source_path.empty() && is_feedback_trace(trace.source_path)) {
    for (std::size_t i = 0; i < cfgs.size(); ++i) {
      try {
        ReplayResult r = run_feedback_replay(*cfgs[i], trace.source_path);
        r.summary.erase("run");
        r.summary.erase("provenance");
        out[i].summary = std::move(r.summary);
        out[i].ok = true;
      } catch (const std::exception& e) {
        out[i].error = e.what();
      }
      if (frames_done) *frames_done += trace.poses.size();
    }
    return out;
  }
  const FramePlan plan = plan_frames(*cfgs[0], trace);
  const ReplayEnv env;
  std::vector<std::unique_ptr<SystemRun>> runs(cfgs.size());
  for (std::size_t i = 0; i < cfgs.size(); ++i) {
    try {
      runs[i] = std::make_unique<SystemRun>(*cfgs[i], plan, scene, env);
    } catch (const std::exception& e) {
      out[i].error = e.what();
    }
  }
  int block_shift = -1;
  bool keep = false, may_keep = false;
  for (const auto& r : runs) {
    if (!r) continue;
    block_shift = r->block_shift();
    keep = keep || !r->system().uses_spans();
    may_keep = may_keep || r->may_keep_samples();
  }
  if (block_shift < 0) return out;  // no run could start

  // One run's frame; an exception stops that run alone (its row says why).
  const auto step = [&](std::size_t i, int f, const FrameView& v, PopinShare& share) {
    if (!runs[i] || !out[i].error.empty()) return;
    try {
      runs[i]->begin_frame(f, plan.target(f));
      runs[i]->step(v, &share);
    } catch (const std::exception& e) {
      out[i].error = e.what();
    }
  };
  // A run's row once its frames are done (on its consumer's thread: the summaries' sorts run in
  // parallel too).
  const auto finish = [&](std::size_t i) {
    if (!runs[i] || !out[i].error.empty()) {
      out[i].ok = false;
      runs[i].reset();
      return;
    }
    try {
      ReplayResult r = runs[i]->summarize(RunCost{});
      // The run's cost and the build are not the row's: sweep.json records the build once
      // (docs/sweep.md), so rows stay byte-identical across builds and machines.
      r.summary.erase("run");
      r.summary.erase("provenance");
      out[i].summary = std::move(r.summary);
      out[i].ok = true;
    } catch (const std::exception& e) {
      out[i].error = e.what();
    }
    runs[i].reset();
  };
  const int consumers = std::max(1, std::min<int>(threads, static_cast<int>(cfgs.size())));
  if (threads <= 1) {
    // One thread: the view rendered in the loop, as run_replay with view.render_threads = 0.
    ViewStream view(*cfgs[0], plan, scene, block_shift, keep, 0);
    PopinShare share;
    for (int f = 0; f < plan.frames; ++f) {
      bool any_keep = false, any_samples = false;
      std::size_t live = 0;
      for (std::size_t i = 0; i < runs.size(); ++i) {
        if (!runs[i] || !out[i].error.empty()) continue;
        ++live;
        any_keep = any_keep || runs[i]->keep_samples();
        any_samples = any_samples || runs[i]->system().wants_samples();
      }
      if (live == 0) break;
      const FrameView& v = view.frame(f, any_keep);
      if (any_samples) materialise_samples(*v.feedback);  // once, before the runs read them
      share.begin_frame(v.popin);
      for (std::size_t i = 0; i < runs.size(); ++i) step(i, f, v, share);
      if (frames_done) frames_done->fetch_add(live, std::memory_order_relaxed);
    }
  } else {
    // The runs split among consumer threads (run i on consumer i mod n), which render the view as
    // they first need it. Samples a run may read are rendered up front: consumers only read the
    // shared buffers.
    ViewRing ring(*cfgs[0], plan, scene, block_shift, keep || may_keep, consumers);
    std::vector<std::thread> pool;
    for (int c = 0; c < consumers; ++c)
      pool.emplace_back([&, c] {
        std::vector<std::size_t> mine;
        for (std::size_t i = static_cast<std::size_t>(c); i < runs.size(); i += static_cast<std::size_t>(consumers))
          mine.push_back(i);
        try {
          for (int f = 0; f < plan.frames; ++f) {
            const FrameView& v = ring.frame(c, f);
            PopinShare& share = ring.share(c);  // every consumer's runs on these spans
            std::uint64_t live = 0;
            for (std::size_t i : mine) {
              if (runs[i] && runs[i]->system().wants_samples() && !v.feedback->has_samples)
                out[i].error = "internal: a run reads samples the shared view did not render";
              step(i, f, v, share);
              live += runs[i] && out[i].error.empty() ? 1 : 0;
            }
            if (frames_done) frames_done->fetch_add(live, std::memory_order_relaxed);
          }
        } catch (const std::exception& e) {
          for (std::size_t i : mine)
            if (out[i].error.empty()) out[i].error = e.what();
        }
        ring.release(c);
        for (std::size_t i : mine) finish(i);
      });
    for (auto& t : pool) t.join();
  }
  if (threads <= 1)
    for (std::size_t i = 0; i < runs.size(); ++i) finish(i);
  return out;
}

}  // namespace vtsim
