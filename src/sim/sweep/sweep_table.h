#pragma once
// A sweep's rows as a pivot table (`vtsim sweep table`, docs/sweep.md, "Tables"): one table per
// metric, one line per value of the row keys, one column per value of the column key, each cell
// the metric of the one row that has those values. Keys are "trace" (the trace's name),
// "trace_file" (its source as the spec wrote it, without the directory), "config"
// (the point's number) or a spec axis; lines and columns keep the order in which the sweep's rows
// first show their values. Two rows landing in one cell is an error that names the axis to add.
// docs/cache.md's policy table is made this way. With the column key "metric", one table instead: a
// line per value of the row keys, a column per metric (docs/produced.md's three systems).
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace vtsim {

struct SweepOutputs {
  nlohmann::json meta;               // sweep.json's "meta" (axes, traces, configs)
  std::vector<nlohmann::json> rows;  // rows.jsonl, in row order
};

// Reads DIR/sweep.json and DIR/rows.jsonl; InputError naming the file (and line) otherwise.
SweepOutputs load_sweep_outputs(const std::string& dir);

struct SweepTableSpec {
  std::vector<std::string> rows;     // keys whose values make a line: "trace", "trace_file", "config" or axes
  std::string col;                   // the key whose values make the columns; "metric": one table, a column per metric
  std::vector<std::string> metrics;  // dotted summary paths (summary_path); one table each
  bool csv = false;                  // CSV (metric,row keys...,column value,value) instead of Markdown
  int digits = 4;                    // significant digits of a cell
};

// The tables. InputError (field "--rows", "--col" or "--metric", with did-you-mean) for a key that
// is not "trace", "config" or an axis, for a metric no row has, and for two rows in one cell.
// A failed row's cell reads "error"; a cell no row fills reads "-".
std::string sweep_table(const SweepOutputs& out, const SweepTableSpec& spec);

}  // namespace vtsim
