#pragma once
// Writing a trace in any registered format (trace_format.h) in that format's own conventions and
// units: the inverse of import_trace, e.g. for the evo trajectory tools (docs/traces.md,
// "Exporters").
#include <string>
#include <string_view>

#include "core/trace.h"

namespace vtsim {

struct ExportOptions {
  std::string world_axes;   // source conventions to write in (parse_world_axes, parse_camera_axes);
  std::string camera_axes;  // empty: the format's TraceFormat::axes, what its import assumes
  // Formats whose poses carry no time (TraceFormat::separate_times: kitti) need exactly one of:
  std::string times_path;   // write the times here, one per line in seconds ("-" = stdout), or
  double rate_hz = 0.0;     // write none, after checking that pose i is at t_0 + i / rate (within
                            // 0.5 ns), which is what an import at this rate gives back
};

// Writes trace to path ("-" = stdout) in the named format: positions and orientations turned into
// the source conventions (to_source_axes), times and numbers in the format's units, doubles in
// their shortest round-trip form. Round trip: import_trace with the format's defaults (and the
// same times file or rate) gives the trace back, with times rebased to the first pose (give a
// trace starting at 0 for the times themselves):
//   native: bit for bit (name, image size and vfov included);
//   the others: positions exact (the axes are a signed permutation), quaternions within ~1e-15 (q
//   or -q), times rounded to whole nanoseconds (the readers' resolution); no name, image size or
//   vfov (the import's defaults come back).
// Throws InputError: unknown format ("format"); a times file or rate for a format that keeps its
// times, neither or both for one that does not ("times"), a bad rate or one that does not give the
// times back ("rate", or path + " pose i"); an invalid trace or two poses within the format's time
// resolution (path + " pose i"); a bad axis spec; a file that cannot be written (path).
void export_trace(const Trace& trace, std::string_view format, const std::string& path,
                  const ExportOptions& options = {});

}  // namespace vtsim
