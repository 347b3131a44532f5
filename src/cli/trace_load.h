#pragma once
// How every command reads a --trace / trace input ("-": stdin): load_any_trace under the repair policy
// (trace_io.h, check_repairs), each repair it made printed as a "vtsim: warning:" line on stderr
// naming the file (warnings are never silenced: issue 26, "Nothing lost silently").
#include <fmt/core.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "cli/cli_io.h"
#include "core/trace.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"

namespace vtsim::cli {

inline void print_repair_warnings(const TraceLoadReport& rep, const std::string& path) {
  for (const std::string& w : repair_warnings(rep.repairs, rep.poses + rep.repairs.dropped(), path))
    warn(w);
}

inline Trace load_cli_trace(const std::string& path, bool allow_repairs, TraceLoadReport* report = nullptr) {
  TraceReadOptions read;
  read.allow_repairs = allow_repairs;
  TraceLoadReport rep;
  Trace t = with_input(path, [&](const std::string& p) { return load_any_trace(p, read, &rep); });
  if (path == "-") t.source_path = "-";  // stdin, not the temporary file it was read through
  print_repair_warnings(rep, path);
  if (report) *report = rep;
  return t;
}

// The --allow-repairs help text, one for every command that reads a trace.
inline constexpr const char* kAllowRepairsHelp =
    "keep a trace whose repairs dropped more than 1 pose and more than 1 % of its poses; each repair is still "
    "printed";

}  // namespace vtsim::cli
