// TUM RGB-D ground truth (Sturm 2012; evo's "tum"): "timestamp tx ty tz qx qy qz qw" per line,
// whitespace-separated, seconds and metres, '#' comments. The poses are the colour camera's
// optical frame in the motion-capture frame (z up).
#include <fmt/compile.h>

#include "sim/trace/impl/format_common.h"
#include "sim/trace/trace_import.h"

namespace vtsim {

namespace {

constexpr format_impl::TimedLayout kTumLayout{
    "tum", "timestamp tx ty tz qx qy qz qw", {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"}, false, false, 9,
    false};

// A whitespace-separated first data line of 8 fields.
bool sniff_tum(const SniffLine& l) { return !l.comment && !l.commas && l.fields.size() == 8; }

SourceTrace read_tum(const std::string& path, const ImportOptions& options) {
  return format_impl::read_timed(path, options.read, kTumLayout);
}

void write_tum(const Trace& trace, const TraceTextSink& poses, const TraceTextSink*, const std::string& where) {
  format_impl::ChunkedText out(poses);
  format_impl::NanosecondTimes times(where, "tum");
  fmt::format_to(out.out(), "# timestamp tx ty tz qx qy qz qw\n");
  for (std::size_t i = 0; i < trace.poses.size(); ++i) {
    const Pose& p = trace.poses[i];
    std::string_view t;
    times.next(p.t_s, i, t);
    // fmt's "{}" for double is the shortest text that reads back to the same bits.
    fmt::format_to(out.out(), FMT_COMPILE("{} {} {} {} {} {} {} {}\n"), t, p.pos_m.x, p.pos_m.y, p.pos_m.z, p.q.x,
                   p.q.y, p.q.z, p.q.w);
    out.line_done();
  }
  out.flush();
}

}  // namespace

TraceFormat trace_format_tum() {
  return {.name = "tum",
          .why = "TUM RGB-D ground truth: 'timestamp tx ty tz qx qy qz qw', seconds, whitespace-separated",
          .axes = {"z-up", "optical"},
          .separate_times = false,
          .sniff_fields = "8",
          .sniff = sniff_tum,
          .read = read_tum,
          .write = write_tum,
          .time_unit_pow10 = 0};
}

}  // namespace vtsim
