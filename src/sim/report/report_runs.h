#pragma once
// `vtsim report RUN.json…`: several replays' summaries side by side in one self-contained HTML
// page (docs/report.md): which run is which, bar charts of the headline metrics per run, latency
// by stage and bandwidth per level per run, then a table of every scalar of the summaries (and of
// their "config" objects when present) with the cells that differ from the first run marked and
// their change in %.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace vtsim {

// The per-frame series of a run's frames CSV (`vtsim replay --frames`) that the page charts.
struct RunFrames {
  std::vector<double> t_s;           // frame time, s
  std::vector<double> disk_bytes;    // read this frame, bytes
  std::vector<double> upload_bytes;  // uploaded this frame, bytes
  std::vector<double> blurry;        // blurry fraction of the frame's samples, 0..1
  std::vector<double> ram_bytes;     // RAM cache occupancy, bytes
};

// Reads a frames CSV; throws InputError naming the file, and the line or column, when it cannot be
// read, lacks one of the columns above, or holds a value that is not a finite number.
RunFrames read_run_frames(const std::string& path);

struct ReportRun {
  std::string name;        // shown in the legend and column heads (the file name by default)
  nlohmann::json summary;  // a replay's summary.json
  RunFrames frames;        // empty unless given (vtsim report --frames)
};

// The page; runs with frames also get charts over time (each run on its own time axis, resampled
// at the first such run's frame times). Runs whose summary is not a JSON object are rejected by the caller (cmd_report).
std::string html_runs_report(const std::vector<ReportRun>& runs);

// Every scalar leaf of a JSON value as (dotted path, value) pairs in document order; arrays of
// objects are indexed by their "level" key when they have one ("per_level.3.upload_MBps"), else
// by position; arrays longer than `max_array` elements (curves, timelines) are left out.
std::vector<std::pair<std::string, nlohmann::json>> flatten_scalars(const nlohmann::json& j, std::size_t max_array = 16);

}  // namespace vtsim
