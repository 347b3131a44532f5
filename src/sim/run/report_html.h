#pragma once
// A self-contained HTML report of a replay (`vtsim replay --report out.html`): the key figures
// and inline SVG charts over time — blurry fraction with cuts and turns marked, the MaxTextureLOD
// clamp against the finest level wanted, disk and upload bytes, requests in flight — and the
// latency distribution. No scripts, no external files: it opens anywhere.
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "sim/run/metrics.h"

namespace vtsim {

// Text for HTML content and attribute values: < > & " ' as entities.
std::string html_escape(std::string_view s);

std::string html_report(const nlohmann::json& summary, const MetricsCollector& metrics);

}  // namespace vtsim
