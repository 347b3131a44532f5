// vtsim report RUN.json…: several replay summaries side by side in one HTML page
// (docs/report.md). The page is built by src/sim/report/report_runs.h.
#include <fmt/format.h>

#include <memory>
#include <string>
#include <vector>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "core/error.h"
#include "sim/compare/compare.h"
#include "sim/report/report_runs.h"

namespace vtsim::cli {

namespace {

struct ReportArgs {
  std::vector<std::string> runs;
  std::vector<std::string> names;
  std::vector<std::string> frames;
  std::string out;
};

// "runs/a/summary.json" -> "a/summary" when the file names repeat, else "summary" -> the stem.
std::string report_run_name(const std::string& path) {
  std::string n = path;
  if (const auto slash = n.find_last_of('/'); slash != std::string::npos) n = n.substr(slash + 1);
  if (n.size() > 5 && n.compare(n.size() - 5, 5, ".json") == 0) n.resize(n.size() - 5);
  return n.empty() ? path : n;
}

void run_report_command(const ReportArgs& a) {
  if (a.runs.empty()) throw InputError("RUN.json", "give at least one replay summary (vtsim replay --summary FILE)");
  if (!a.names.empty() && a.names.size() != a.runs.size())
    throw InputError("--names", fmt::format("{} names for {} runs: give one name per run, in order", a.names.size(), a.runs.size()));
  if (!a.frames.empty() && a.frames.size() != a.runs.size())
    throw InputError("--frames", fmt::format("{} frames CSVs for {} runs: give one per run, in order", a.frames.size(),
                                             a.runs.size()));
  if (a.out.empty()) throw InputError("-o", "an output file is required (-o report.html, or -o - for stdout)");
  check_output("-o", a.out);  // before reading the runs: a bad path fails first
  std::vector<ReportRun> runs;
  for (std::size_t i = 0; i < a.runs.size(); ++i) {
    nlohmann::json s = load_json_file(a.runs[i]);
    if (!s.is_object() || !(s.contains("provenance") || s.contains("vtsim_version") || s.contains("latency_ms")))
      throw InputError(a.runs[i], "not a replay summary (no \"vtsim_version\" or \"latency_ms\"; write one with vtsim replay --summary)");
    runs.push_back({a.names.empty() ? report_run_name(a.runs[i]) : a.names[i], std::move(s), {}});
    if (!a.frames.empty() && !a.frames[i].empty()) runs.back().frames = read_run_frames(a.frames[i]);
  }
  // Names that repeat (every file called summary.json) get their directory back.
  for (std::size_t i = 0; i < runs.size() && a.names.empty(); ++i)
    for (std::size_t j = 0; j < runs.size(); ++j)
      if (i != j && runs[i].name == report_run_name(a.runs[j])) {
        runs[i].name = a.runs[i];
        break;
      }
  write_output(a.out, html_runs_report(runs));  // whole or not at all: a failed run leaves the old page
}

}  // namespace

void register_report_commands(CLI::App& app) {
  auto a = std::make_shared<ReportArgs>();
  auto* c = app.add_subcommand("report", "Several replays' summaries side by side in one HTML page (docs/report.md)");
  c->add_option("runs", a->runs, "summary JSON files (vtsim replay --summary FILE), the first is the reference")->required();
  c->add_option("-o,--out", a->out, "write the HTML page here (- for stdout)")->required();
  c->add_option("--names", a->names, "a name per run for legends and columns (default: the file names)")->delimiter(',');
  c->add_option("--frames", a->frames, "each run's frames CSV (vtsim replay --frames), comma separated, one per run: adds charts "
                                       "over time")->delimiter(',');
  c->callback([a] { run_report_command(*a); });
}

}  // namespace vtsim::cli
