#pragma once
// Importing recorded trajectories (TUM RGB-D, EuRoC MAV ground truth, KITTI odometry poses; the
// formats of the evo trajectory tool) and format detection (docs/traces.md, "Importers"). The
// formats themselves are the entries of trace_format.h.
#include <cstdint>
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

// The plausible mean pose rate of a recording: 1 Hz (GPS, sparse keyframes) to 10 kHz (fast
// motion capture) widened by a decade each way. A time unit mistaken reads the rate wrong by a
// factor of 1e3 to 1e9 (seconds as nanoseconds: 1e9), far outside even the widened range.
inline constexpr double kMinPlausibleRate_hz = 0.1;
inline constexpr double kMaxPlausibleRate_hz = 1e5;
// Fewer poses than this say too little about their rate to refuse a file for it.
inline constexpr std::int64_t kTimeUnitCheckMinPoses = 10;

// Throws InputError(path, "N poses span S s (R Hz), far outside 1 Hz-10 kHz: ...") naming the likely
// unit and the --time-scale that would fix it, when poses >= kTimeUnitCheckMinPoses and the mean
// rate (poses - 1) / span_s is outside [kMinPlausibleRate_hz, kMaxPlausibleRate_hz] (span_s <= 0:
// infinite). unit_pow10: the format's unit (TraceFormat::time_unit_pow10); time_scale: the
// --time-scale already applied to span_s.
void check_time_units(std::int64_t poses, double span_s, int unit_pow10, double time_scale, std::string_view format,
                      const std::string& path);

// The name of the format of path, by asking the formats' sniffs (trace_format.h) in table order
// about each line up to the first data line. Today's rules: a first line starting "# vtsim-trace"
// -> native, and so is a first data line starting "t_s" (a native header: the native reader names
// what is missing); a "p_RS_R_x" header or a comma-separated first data line with >= 8 fields and
// an integer first field -> euroc; a whitespace-separated first data line with 8 fields -> tum,
// with 12 -> kitti. Throws InputError("path:line", ...) asking for --format when none fits (a
// comma-separated line whose time has a fraction: TUM with commas or EuRoC in seconds, refused).
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
// an InputError("format", ...). Refuses implausible time units (check_time_units, after the
// transform's --time-scale) and more dropped poses than check_repairs allows
// (options.read.allow_repairs); the repairs made are in report->repairs.
Trace import_trace(const std::string& path, const ImportOptions& options = {},
                   TraceLoadReport* report = nullptr);

// Native files exactly as stored (load_trace); other formats through import_trace with defaults.
// Sets the trace's source_path (path) and source_hash (FNV-1a 64 of the file's bytes).
Trace load_any_trace(const std::string& path, const TraceReadOptions& read = {},
                     TraceLoadReport* report = nullptr);

}  // namespace vtsim
