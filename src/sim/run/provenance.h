#pragma once
// What a run was, besides its metrics (docs/metrics.md, "What the run was"): the summary's schema
// name, the build (version, git commit, compiler), the machine of a real-clock run, the effective
// config as JSON and the trace's identity. Pure functions but machine_json (reads /proc, uname).
#include <nlohmann/json.hpp>
#include <string>

#include "core/trace.h"
#include "sim/run/replay_config.h"

namespace vtsim {

// The summary's "schema": its name and major version. The version goes up when a key changes
// meaning or disappears (a new key does not change it); docs/metrics.md lists the keys of each.
inline constexpr const char* kSummarySchema = "vtsim-summary/1";

// {"vtsim_version", "vtsim_commit", "compiler", "optimized"}: changes with every build, so kept
// out of comparisons and golden files (the summary's "provenance" section).
nlohmann::json build_json();

// The machine a real-clock run measured: {"hostname", "cpu", "logical_cores", "memory_GiB", "os"}.
// Fields that cannot be read are "unknown" (strings) or 0.
nlohmann::json machine_json();

// Every key of the config table (replay_config_table(), docs/config.md) with its effective value,
// defaults included, as one flat object keyed like --set ("disk.preset": "hdd"): integers, reals,
// booleans and strings as JSON numbers, booleans and strings.
nlohmann::json config_json(const ReplayConfig& cfg);

// "fnv1a64:" and 16 hex digits of a trace's source_hash; null JSON when it has none (generated).
nlohmann::json trace_hash_json(const Trace& trace);

}  // namespace vtsim
