#pragma once
// The summary's "resources" section: what a run of any streaming system costs, in the same fields
// for the streamed VT, the streamed clipmap and the produced clipmap (the terrain), so that
// `vtsim sweep table` can set them side by side (docs/produced.md, "Three systems side by side";
// docs/metrics.md). Memory from the config's closed forms (the same as `vtsim capacity`), the peaks
// and the production time per frame from the run's frame rows. Pure; O(frames + levels).
#include <nlohmann/json.hpp>

#include "sim/run/metrics.h"
#include "sim/run/replay_config.h"
#include "stream/system/i_system.h"

namespace vtsim {

// `system_stats` is the system's stats_json() (the VT pool's bytes come from it).
nlohmann::json resources_json(const ReplayConfig& cfg, const IStreamingSystem& system, const nlohmann::json& system_stats,
                              const MetricsCollector& metrics);

}  // namespace vtsim
