#pragma once
// The report of a sweep (`vtsim sweep`, docs/sweep.md, "The sweep report"): one HTML page from the sweep's meta
// (name, spec hash, axes, configs with their costs, traces, metrics) and its rows (one per
// (config, trace): the replay summary, or the error that stopped it). The page shows the
// failed rows, each metric over each axis, each metric per trace, and the Pareto front of
// pop-in against each cost that varies. Rows are matched by their "config" and "trace" fields,
// not by their order; a metric path that is missing or not a number shows as "n/a".
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

namespace vtsim {

// The sweep report: self-contained HTML (inline SVG and CSS, no scripts needed, no network), a pure
// function of its inputs (same inputs, same bytes: shards merged must equal the unsharded run).
std::string sweep_report_html(const nlohmann::json& meta, const std::vector<nlohmann::json>& rows);

// Indices of the points not dominated when both coordinates are to be minimised (x = cost, y = pop-in),
// sorted by x; ties: a point equal to another in both is kept once (the lower index).
std::vector<std::size_t> pareto_front(const std::vector<std::pair<double, double>>& points);

}  // namespace vtsim
