#pragma once
// View once, systems many (docs/sweep.md): one trace's view rendered once per frame and several
// configs' streaming systems stepped on it in lockstep (frame_loop.h: one ViewStream, many
// SystemRuns). Each config's summary is exactly its `run_replay` alone (tests/test_sweep.cpp over
// every system and throttle policy), because the view depends only on view_key() and every run
// keeps its own state; the shared buffers are written by the view alone (samples are expanded
// once, before the runs read them).
//
// Parallelism: the runs of a frame are stepped by a team of threads (StepTeam) while render-ahead
// renders the next frames; results do not depend on the thread count.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "core/trace.h"
#include "sim/run/replay_config.h"

namespace vtsim {

class IScene;

// What two configs must share to share one rendered view: run.fps, the texture's size and
// placement, the scene, the [view] section but render_threads, and log2 of the tile size (spans
// never cross a tile).
std::string view_key(const ReplayConfig& cfg);

// A team of `threads` (the caller and threads - 1 workers) that runs fn(0..n-1) per call, each
// index once, and returns when all are done. Workers sleep between calls (std::atomic wait).
// Not reentrant; one caller thread.
class StepTeam {
 public:
  explicit StepTeam(int threads);
  ~StepTeam();
  StepTeam(const StepTeam&) = delete;
  StepTeam& operator=(const StepTeam&) = delete;
  int threads() const { return static_cast<int>(workers_.size()) + 1; }
  void run(std::size_t n, const std::function<void(std::size_t)>& fn);

 private:
  void pull();
  void work();
  std::vector<std::thread> workers_;
  // A call's state: published by bumping generation_ (release), read by workers after they see it.
  std::atomic<std::uint64_t> generation_{0};   // odd counts nothing: a new call; kStop: exit
  std::atomic<std::size_t> next_{0};           // next index to claim
  std::atomic<std::size_t> checked_in_{0};     // workers still inside the current call
  std::size_t n_ = 0;
  const std::function<void(std::size_t)>* fn_ = nullptr;
  static constexpr std::uint64_t kStop = ~std::uint64_t{0};
};

struct LockstepResult {
  bool ok = false;
  std::string error;        // when !ok: why the run failed (the others went on)
  nlohmann::json summary;   // the replay summary without its "run" cost section
};

// Replays `trace` once per config on one view. All configs must have the same view_key()
// (std::invalid_argument otherwise). `threads` >= 1 steps the runs on a team and renders ahead on
// one more thread when > 1. `frames_done` (optional) is advanced by the runs' frames as they go.
// Throws InputError for a trace without poses.
std::vector<LockstepResult> run_lockstep(const std::vector<const ReplayConfig*>& cfgs, const Trace& trace,
                                         const IScene& scene, int threads,
                                         std::atomic<std::uint64_t>* frames_done = nullptr);

}  // namespace vtsim
