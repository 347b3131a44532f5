#pragma once
// A whole replay in one call: a trace drives one streaming system (clipmap, virtual texture or produced terrain)
// through the request pipeline in the simulated clock (device models) or the real clock (real
// files and threads), and measures latency, pop-in and bandwidth (docs/architecture.md,
// docs/metrics.md). The frame loop's steps are in frame_loop.h.
#include <memory>

#include "core/trace.h"
#include "sim/run/frame_loop.h"
#include "sim/run/replay_config.h"
#include "sim/view/scene.h"

namespace vtsim {

class IScene;

// The scene parameters a config names, over the config's texture (what make_scene_from_config
// builds; `vtsim view -c` starts from them).
SceneConfig scene_config_of(const ReplayConfig& cfg);
// The scene a config names, over the config's texture; throws InputError when the scene's
// texture differs from texture.width × height.
std::unique_ptr<IScene> make_scene_from_config(const ReplayConfig& cfg);

// Runs a whole trace: the plan, one view and one system, frame by frame. The trace is resampled
// to run.fps first (unless 0). Throws InputError for bad input (empty trace, image size, ...).
ReplayResult run_replay(const ReplayConfig& cfg, const Trace& trace, const IScene& scene, const ReplayEnv& env = {});

// A simulated replay that records each level's access sequence (AccessLogs), with its summary.
struct RecordedReplay {
  AccessLogs accesses;
  ReplayResult result;
};
RecordedReplay record_accesses(const ReplayConfig& cfg, const Trace& trace, const IScene& scene);
// The same on the scene the config names (make_scene_from_config).
RecordedReplay record_accesses(const ReplayConfig& cfg, const Trace& trace);

}  // namespace vtsim
