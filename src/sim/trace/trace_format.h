#pragma once
// The trace formats vtsim reads and writes, one registry entry each (core/registry.h): the native
// CSV and the formats of the evo trajectory tools (TUM RGB-D, EuRoC MAV, KITTI odometry).
// docs/traces.md, "Adding a trace format": a format is one file impl/format_<name>.cpp defining
// its entry (detection rule, reader, writer) and one line in trace_format_registry.cpp. Import,
// export and detection (trace_import.h, trace_export.h), the CLI's --format lists and errors, and
// the table in docs/traces.md all read the entries.
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "core/registry.h"
#include "core/trace.h"
#include "sim/trace/trace_io.h"

namespace vtsim {

struct ImportOptions;  // trace_import.h

// The source conventions a format's poses are in when the user does not say otherwise.
struct FormatAxes {
  const char* world;   // parse_world_axes spec
  const char* camera;  // parse_camera_axes spec
};

// What a reader returns: poses still in the format's source axes and, for a format with
// timestamps of its own, times relative to the first pose (exact: from integer nanoseconds).
struct SourceTrace {
  Trace trace;                 // name set by the reader; vfov and image size left at the defaults
  std::optional<double> t0_s;  // absolute time of the first pose, seconds, when the times are
                               // relative to it; nullopt: times as stored (native)
  std::int64_t lines = 0;      // lines read, including comments and blank lines
  TraceRepairs repairs;
};

// What detection (detect_trace_format) shows a format's sniff: each non-blank line, in order, up
// to and including the first line that is not a comment.
struct SniffLine {
  std::int64_t line_no = 0;                  // 1-based
  std::string_view text;                     // the line as read
  bool comment = false;                      // its first non-blank character is '#'
  bool commas = false;                       // a data line containing ','
  std::span<const std::string_view> fields;  // comment: the whitespace-separated words after the
                                             // '#'; data: the comma-separated fields when commas,
                                             // else the whitespace-separated ones
};

// Where a writer's text goes, piece by piece, in order.
using TraceTextSink = std::function<void(std::string_view)>;

struct TraceFormat {
  std::string_view name;  // --format value, TraceLoadReport::format
  std::string_view why;   // one line: what the format is
  FormatAxes axes;        // default source conventions: import converts from them, export to them
  // The poses carry no time (KITTI): import takes a times file or a rate (ImportOptions), export
  // writes a times file or checks a rate (ExportOptions).
  bool separate_times = false;
  // The data-line rule in words for detection's "cannot tell" error, completing "<name> has ...":
  // "8" (fields); empty when the format is not told by its data lines.
  std::string_view sniff_fields;
  // True when a file showing this line (see SniffLine) is in this format. Detection asks the
  // entries in table order and takes the first yes; a data line nobody claims is an error.
  bool (*sniff)(const SniffLine& line) = nullptr;
  // Reads path in this format (options.read: limits and strictness; KITTI: the times). Throws
  // InputError("path:line", ...) for bad input; repairs per TraceRepairs.
  SourceTrace (*read)(const std::string& path, const ImportOptions& options) = nullptr;
  // Writes a valid trace whose poses are already in this format's source axes (to_source_axes).
  // The times go to `times` when the format keeps them apart (separate_times) and the caller asked
  // for a times file; otherwise `times` is null. Throws InputError(where + " pose i", ...) for a trace the
  // format cannot give back (two times within the format's resolution).
  void (*write)(const Trace& trace, const TraceTextSink& poses, const TraceTextSink* times,
                const std::string& where) = nullptr;
  // The unit of the source times as one power of ten of seconds (0: seconds, -9: nanoseconds), for
  // import's check of implausible rates (check_time_units); nullopt: not checked (native: as stored).
  std::optional<int> time_unit_pow10;
};

// The table (trace_format_registry.cpp), in detection order.
const Registry<TraceFormat>& trace_formats();

}  // namespace vtsim
