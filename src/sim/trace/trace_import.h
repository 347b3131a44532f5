#pragma once
// Importing recorded trajectories (TUM RGB-D, EuRoC MAV ground truth, KITTI odometry poses; the
// formats of the evo trajectory tool) and format detection (docs/traces.md, "Importers"). The
// formats themselves are the entries of trace_format.h.
#include <string>
#include <string_view>

#include "core/trace.h"
#include "sim/trace/trace_format.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_transform.h"

namespace vtsim {

// The registry's entry named `name` ("native", "tum", ...: trace_formats().names()). Throws
// InputError(where, "unknown trace format 'x' (one of: ...; did you mean 'y'?)") otherwise.
const TraceFormat& parse_trace_format(std::string_view name, const std::string& where);

// The name of the format of path, by asking the formats' sniffs (trace_format.h) in table order
// about each line up to the first data line. Today's rules: a first line starting "# vtsim-trace"
// -> native; a "p_RS_R_x" header or a comma-separated first data line with >= 8 fields -> euroc; a
// whitespace-separated first data line with 8 fields -> tum, with 12 -> kitti. Throws
// InputError("path:line", ...) when none fits.
std::string detect_trace_format(const std::string& path, const TraceReadLimits& limits = {});

struct ImportOptions {
  std::string format;                 // a trace_formats() name; empty: detect_trace_format
  std::string kitti_times_path;       // KITTI: a file with one time (s) per pose, or:
  double kitti_rate_hz = 0.0;         // KITTI: t_i = i / rate (10 Hz for KITTI odometry)
  TraceTransform transform;           // empty axis specs: the format's TraceFormat::axes
  int image_width = 0;                // > 0: set the trace's image size (pixels); 0: keep the
  int image_height = 0;               // native file's, or 1920x1080 for the other formats
  TraceReadOptions read;
};

// Reads path in its format, then applies options.transform (trace_transform.h). Times are read
// as exact integer nanoseconds and rebased before conversion to double seconds, so a 2011 Unix
// time keeps its 0.1 ms digits. The result satisfies validate_trace. An unknown options.format is
// an InputError("format", ...).
Trace import_trace(const std::string& path, const ImportOptions& options = {},
                   TraceLoadReport* report = nullptr);

// Native files exactly as stored (load_trace); other formats through import_trace with defaults.
// Sets the trace's source_path (path) and source_hash (FNV-1a 64 of the file's bytes).
Trace load_any_trace(const std::string& path, const TraceReadOptions& read = {},
                     TraceLoadReport* report = nullptr);

}  // namespace vtsim
