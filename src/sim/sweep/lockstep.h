#pragma once
// View once, systems many (docs/sweep.md): one trace's view rendered once per frame and several
// configs' streaming systems stepped on it in lockstep (frame_loop.h: one ViewStream, many
// SystemRuns). Each config's summary is exactly its `run_replay` alone (tests/test_sweep.cpp over
// every system and throttle policy), because the view depends only on view_key() and every run
// keeps its own state; the shared buffers are written by the view alone (samples are expanded
// once, before the runs read them).
//
// Parallelism: with threads > 1 the runs are split among `threads` consumer threads, each
// stepping its runs through every frame; the frames are rendered into a ring of buffers by the
// consumer that first needs each (the last consumer also renders ahead while it is close behind
// the others, so that they meet new states first and it copies their pop-in), and a frame's
// buffers are freed when every consumer has moved past them (no barrier per frame: a consumer
// waits only for a render another is doing, or for the slowest consumer when the ring is full). A group that may
// read every sample (SystemRun::may_keep_samples) has them rendered up front, so consumers never
// write the shared buffers. Results do not depend on the thread count.
#include <atomic>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/trace.h"
#include "sim/run/replay_config.h"

namespace vtsim {

class IScene;

// What two configs must share to share one rendered view: run.fps, the texture's size and
// placement, the scene, the [view] section but render_threads, and log2 of the tile size (spans
// never cross a tile).
std::string view_key(const ReplayConfig& cfg);

struct LockstepResult {
  bool ok = false;
  std::string error;        // when !ok: why the run failed (the others went on)
  nlohmann::json summary;   // the replay summary without its "run" cost section
};

// Replays `trace` once per config on one view. All configs must have the same view_key()
// (std::invalid_argument otherwise). `threads` >= 1: threads stepping the runs and rendering the
// view (at most one per run). `frames_done` (optional) is advanced by the runs' frames as they go.
// Throws InputError for a trace without poses. A feedback trace (trace.source_path starts with its
// magic, docs/feedback.md) has no view to share: each config replays it alone (run_feedback_replay).
std::vector<LockstepResult> run_lockstep(const std::vector<const ReplayConfig*>& cfgs, const Trace& trace,
                                         const IScene& scene, int threads,
                                         std::atomic<std::uint64_t>* frames_done = nullptr);

}  // namespace vtsim
