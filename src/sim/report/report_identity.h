#pragma once
// The part of the HTML report that says what the run was (docs/metrics.md, "What the run was"):
// the build, the machine of a real-clock run, the trace's identity and every config key.
#include <nlohmann/json.hpp>
#include <string>

namespace vtsim {

// An HTML fragment (a heading, a table, the config in a <details> table) from a summary's
// provenance, trace and config sections; those a summary lacks are left out.
std::string html_run_identity(const nlohmann::json& summary);

}  // namespace vtsim
