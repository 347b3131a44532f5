#pragma once
// The frame loop: a trace drives a streaming system (clipmap or virtual texture) through the
// request pipeline in the simulated clock (device models) or the real clock (real files and
// threads), and measures latency, pop-in and bandwidth (docs/architecture.md, docs/metrics.md).
//
// One frame, in order: collect completions up to the frame's time; render the feedback; the
// system places its windows / reads the feedback; the throttling policy sets MaxTextureLOD;
// needs are diffed against what is in flight (cancelling what is no longer needed); queued work is
// dispatched; uploads are chosen within the budget and committed; pop-in is measured before and
// after the commits; a row of metrics is recorded.
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "sim/run/metrics.h"
#include "sim/run/replay_config.h"
#include "core/trace.h"
#include "stream/exec/i_executor.h"
#include "stream/exec/pipeline.h"

namespace vtsim {

class IScene;
class IStreamingSystem;

struct ReplayEnv {
  // The real clock: an executor doing real IO and decode, and a pacer that waits until a frame's
  // target time (ticks since start) and returns the actual time the frame starts. Both null: the
  // simulated clock from the config's device models.
  IExecutor* executor = nullptr;
  std::function<Ticks(int frame, Ticks target)> pace;
  // Per-tile sizes; null: from the config's layer formats and compression ratios.
  TileSizer sizer;
  // Called after each uploaded tile with its VRAM slot (IStreamingSystem::vram_slot; real clock:
  // copy into the VRAM arena).
  std::function<void(const UploadItem&, std::int64_t slot)> on_upload;
  // Called once after the last frame with the system as it ended (real clock: check VRAM).
  std::function<void(const IStreamingSystem&)> on_finish;
  // Progress callback (frame, frames), called about once a second of wall time.
  std::function<void(int, int)> progress;
  std::string clock_name = "simulated";
};

struct ReplayResult {
  nlohmann::json summary;
  MetricsCollector metrics;
};

// The streaming system a config names ("clipmap" or "vt") over the scene's texture.
std::unique_ptr<IStreamingSystem> make_system(const ReplayConfig& cfg, const IScene& scene);
// The scene a config names.
std::unique_ptr<IScene> make_scene_from_config(const ReplayConfig& cfg);

// Runs a whole trace. The trace is resampled to cfg.fps first (unless 0). Throws InputError for
// bad input (empty trace, image size, ...).
ReplayResult run_replay(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const ReplayEnv& env = {});

// A short human summary of a result (what `vtsim replay` prints).
std::string format_summary(const nlohmann::json& summary);

}  // namespace vtsim
