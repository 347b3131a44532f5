#pragma once
// A metric's address in a replay summary (docs/metrics.md): a dotted path, and patterns over
// paths. Read by `vtsim compare`, the metric directions, the sweep's CSV, tables, report and
// tune's constraints. Pure functions; thread-safe.
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace vtsim {

// The value at a metric's dotted path in a replay summary ("popin.time_to_sharp_s.mean"; array
// elements by number: "bandwidth.per_level.0.disk_read_MBps"), or nullptr. The CSV, the report
// and tune's constraints all read metrics through it.
const nlohmann::json* summary_path(const nlohmann::json& summary, std::string_view dotted);

// Whether `pattern` ('*' wildcards) matches the whole of `key`.
bool glob_match(const std::string& pattern, const std::string& key);

}  // namespace vtsim
