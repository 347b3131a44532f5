// The replay summary's measured sections (docs/metrics.md), built once for every client of a
// StreamingRuntime: the simulated and real clocks' frame loop (frame_loop.cpp) and the GL client
// (gl/gl_replay.cpp). One builder, so a section added for one clock reaches the others.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "core/time.h"

namespace vtsim {

struct ReplayConfig;
struct FramePlan;
class Pipeline;
class IStreamingSystem;
class MetricsCollector;
class SimExecutor;

struct SummaryInputs {
  const ReplayConfig& cfg;           // the effective config (its JSON goes into "config")
  const FramePlan& plan;             // the trace and frames run
  const std::string& clock;          // "sim", "real", "gl": the summary's "clock"
  const Pipeline& pipe;              // counters, requests that ended unserved, open demand
  const IStreamingSystem& system;    // its stats section, VRAM evictions, never-sampled bytes
  MetricsCollector& metrics;         // per-frame rows and latencies; level bytes and unserved added here
  const std::uint64_t* level_upload;  // bytes uploaded per level, system.num_levels() entries
  Ticks end;                          // the run's end: requests still open are censored there
  const SimExecutor* sim = nullptr;   // the simulated executor (production busy time), else null
};

// Fills `s` with schema, provenance, config, system, clock, trace, bandwidth (steady-state rates
// after metrics.warmup_s), latency_ms (censored: docs/metrics.md), popin, startup, cache, throttle,
// faults, produce (when tiles were produced), the system's section and resources. Not "run" (the
// driver's own cost) nor a client's own sections.
void fill_run_summary(nlohmann::json& s, const SummaryInputs& in);

// Peak resident set of this process, MB (getrusage; Linux reports KiB).
double peak_rss_MB();

}  // namespace vtsim
