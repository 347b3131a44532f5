// The native format (trace_io.h): vtsim's own CSV, read exactly as stored and written bit-exact.
#include <optional>

#include "sim/trace/trace_format.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"

namespace vtsim {

namespace {

// The magic first line: "# vtsim-trace v1 ...". Also a native column header ("t_s,...") as the first
// data line, even a damaged one: the native reader then names what is wrong (the missing magic line
// or column) rather than another format's reader failing on field 't_s'.
bool sniff_native(const SniffLine& l) {
  if (l.comment) return l.line_no == 1 && !l.fields.empty() && l.fields[0] == "vtsim-trace";
  return !l.fields.empty() && l.fields[0] == "t_s";
}

SourceTrace read_native(const std::string& path, const ImportOptions& options) {
  TraceLoadReport r;
  SourceTrace s;
  s.trace = load_trace(path, options.read, &r);
  s.lines = r.lines;
  s.repairs = r.repairs;
  return s;  // t0_s unset: the times as stored
}

void write_native(const Trace& trace, const TraceTextSink& poses, const TraceTextSink*, const std::string&) {
  write_trace_text(trace, poses);
}

}  // namespace

TraceFormat trace_format_native() {
  return {.name = "native",
          .why = "vtsim's own: a '# vtsim-trace v1' line, then CSV 't_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg'; "
                 "bit-exact",
          .axes = {"ENU", "FLU"},
          .separate_times = false,
          .sniff_fields = "",
          .sniff = sniff_native,
          .read = read_native,
          .write = write_native,
          .time_unit_pow10 = std::nullopt};
}

}  // namespace vtsim
