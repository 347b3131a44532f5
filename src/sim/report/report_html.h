#pragma once
// A self-contained HTML report of a replay (`vtsim replay --report out.html`): the key figures,
// the effective config, and inline SVG charts (svg_chart.h) over time — blurry fraction with cuts
// and turns marked, the MaxTextureLOD clamp against the finest level wanted, disk and upload
// bandwidth, upload per frame against its budget, RAM and VT pool occupancy, pool pressure and
// bias, requests in the pipeline — the latency distribution in ms, latency by stage and bandwidth
// per level. No external files: it opens anywhere. One inline script runs only when the page is
// opened with `?check` (report_check_script). docs/report.md describes every chart.
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sim/run/metrics.h"

namespace vtsim {

// "0.1.0 (commit 0b8eebf307ea)" from a summary's provenance (schema vtsim-summary/1), or the
// top-level vtsim_version of older summaries; "?" when neither is there.
std::string summary_version(const nlohmann::json& summary);

// The effective config as (dotted key, value in TOML syntax) pairs, in table order.
using ReportConfig = std::vector<std::pair<std::string, std::string>>;

// `config` empty: the summary's own "config" object, when it has one, is shown instead.
std::string html_report(const nlohmann::json& summary, const MetricsCollector& metrics, const ReportConfig& config = {});

// Every report's <head>: charset, title, the shared stylesheet and report_check_script().
std::string report_page_head(const std::string& title);

// A script that does nothing unless the page's URL has `?check`: then, after load, it measures
// every text of every chart (getBoundingClientRect), and appends to the body a
// <pre id="vtsim-check"> whose first line is "VTSIM-CHECK charts=N texts=N overlaps=N
// console_errors=N" followed by one line per problem: two texts of a chart overlapping by more
// than 1 px both ways, a text outside its chart, an error on the console or an uncaught exception.
// tests/browser/report_browser.sh reads it through `chromium --headless --dump-dom`.
std::string report_check_script();

// The config of a summary's "config" object (nested objects flattened to dotted keys; strings
// quoted as TOML does); empty when there is none.
ReportConfig report_config_of(const nlohmann::json& summary);

}  // namespace vtsim
