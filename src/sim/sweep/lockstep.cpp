#include "sim/sweep/lockstep.h"

#include <bit>
#include <memory>
#include <stdexcept>

#include "core/error.h"
#include "core/view_spans.h"
#include "sim/run/frame_loop.h"
#include "stream/system/i_system.h"

namespace vtsim {

std::string view_key(const ReplayConfig& cfg) {
  std::string key;
  for (const auto& f : replay_config_table().fields()) {
    const bool view = f.key.rfind("view.", 0) == 0 && f.key != "view.render_threads";
    const bool scene = f.key.rfind("scene.", 0) == 0;
    const bool texture = f.key == "texture.width" || f.key == "texture.height" || f.key == "texture.texels_per_m" ||
                         f.key == "texture.origin_x_m" || f.key == "texture.origin_y_m";
    if (view || scene || texture || f.key == "run.fps") key.append(f.key).append("=").append(f.get(cfg)).append("\n");
  }
  key += "block_shift=" + std::to_string(std::bit_width(static_cast<unsigned>(cfg.texture.tile_size)) - 1) + "\n";
  return key;
}

// ---- StepTeam ----

StepTeam::StepTeam(int threads) {
  for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { work(); });
}

StepTeam::~StepTeam() {
  generation_.store(kStop, std::memory_order_release);
  generation_.notify_all();
  for (auto& t : workers_) t.join();
}

void StepTeam::pull() {
  for (;;) {
    const std::size_t i = next_.fetch_add(1, std::memory_order_relaxed);
    if (i >= n_) return;
    (*fn_)(i);
  }
}

void StepTeam::work() {
  std::uint64_t seen = 0;
  for (;;) {
    generation_.wait(seen, std::memory_order_acquire);
    seen = generation_.load(std::memory_order_acquire);
    if (seen == kStop) return;
    pull();
    // Checked out: every index this worker claimed is done, and it claims no more in this call.
    if (checked_in_.fetch_sub(1, std::memory_order_acq_rel) == 1) checked_in_.notify_one();
  }
}

void StepTeam::run(std::size_t n, const std::function<void(std::size_t)>& fn) {
  n_ = n;
  fn_ = &fn;
  next_.store(0, std::memory_order_relaxed);
  if (workers_.empty()) {
    pull();
    return;
  }
  checked_in_.store(workers_.size(), std::memory_order_relaxed);
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_all();
  pull();
  for (std::size_t c = checked_in_.load(std::memory_order_acquire); c != 0; c = checked_in_.load(std::memory_order_acquire))
    checked_in_.wait(c, std::memory_order_acquire);
}

// ---- run_lockstep ----

std::vector<LockstepResult> run_lockstep(const std::vector<const ReplayConfig*>& cfgs, const Trace& trace,
                                         const IScene& scene, int threads, std::atomic<std::uint64_t>* frames_done) {
  std::vector<LockstepResult> out(cfgs.size());
  if (cfgs.empty()) return out;
  const std::string key = view_key(*cfgs[0]);
  for (const ReplayConfig* c : cfgs)
    if (view_key(*c) != key) throw std::invalid_argument("run_lockstep: configs with different views");
  const FramePlan plan = plan_frames(*cfgs[0], trace);
  const ReplayEnv env;
  std::vector<std::unique_ptr<SystemRun>> runs(cfgs.size());
  const auto fail = [&](std::size_t i, std::string what) {
    out[i].ok = false;
    out[i].error = std::move(what);
    out[i].summary = nullptr;
    runs[i].reset();
  };
  for (std::size_t i = 0; i < cfgs.size(); ++i) {
    try {
      runs[i] = std::make_unique<SystemRun>(*cfgs[i], plan, scene, env);
      out[i].ok = true;
    } catch (const std::exception& e) {
      fail(i, e.what());
    }
  }
  int block_shift = -1;
  bool keep = false;
  for (const auto& r : runs) {
    if (!r) continue;
    block_shift = r->block_shift();
    keep = keep || !r->system().uses_spans();
  }
  if (block_shift < 0) return out;  // every run failed to start

  // Render-ahead on one thread beside a team; in the loop when the sweep gives this view one core.
  ReplayConfig vc = *cfgs[0];
  vc.view.render_threads = threads > 1 ? 1 : 0;
  StepTeam team(threads);
  ViewStream view(vc, plan, scene, block_shift, keep, ViewStream::resolve_threads(vc, plan, false));
  std::vector<std::size_t> live;
  const FrameView* v = nullptr;
  int frame = 0;
  const std::function<void(std::size_t)> step = [&](std::size_t k) {
    const std::size_t i = live[k];
    try {
      runs[i]->begin_frame(frame, plan.target(frame));
      runs[i]->step(*v);
    } catch (const std::exception& e) {
      out[i].error = e.what();  // this run alone stops; collected after the frame
    }
  };
  for (frame = 0; frame < plan.frames; ++frame) {
    live.clear();
    bool any_keep = false, any_samples = false;
    for (std::size_t i = 0; i < runs.size(); ++i) {
      if (!runs[i]) continue;
      live.push_back(i);
      any_keep = any_keep || runs[i]->keep_samples();
      any_samples = any_samples || runs[i]->system().wants_samples();
    }
    if (live.empty()) break;
    v = &view.frame(frame, any_keep);
    // The runs read the shared buffers only: expand the samples here, once, if any run reads them.
    if (any_samples) materialise_samples(*v->feedback);
    team.run(live.size(), step);
    for (std::size_t i : live)
      if (!out[i].error.empty()) fail(i, out[i].error);
    if (frames_done) frames_done->fetch_add(live.size(), std::memory_order_relaxed);
  }
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (!runs[i]) continue;
    try {
      ReplayResult r = runs[i]->summarize(RunCost{});
      r.summary.erase("run");
      out[i].summary = std::move(r.summary);
    } catch (const std::exception& e) {
      fail(i, e.what());
    }
  }
  return out;
}

}  // namespace vtsim
