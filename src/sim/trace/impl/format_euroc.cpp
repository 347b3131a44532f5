// EuRoC MAV ground truth (Burri 2016; evo's "euroc"): "timestamp, p x y z, q w x y z, ..." per
// line, comma-separated, integer nanoseconds and metres; the columns after the 8th (velocities,
// biases) are ignored. The pose is the IMU body's (x up, y right, z forward: cam0's optical axis
// is body z within 1.5 degrees) in the Vicon frame (z up).
#include <fmt/compile.h>

#include "sim/trace/impl/format_common.h"
#include "sim/trace/trace_import.h"

namespace vtsim {

namespace {

constexpr format_impl::TimedLayout kEurocLayout{"euroc",
                                                "timestamp_ns, px, py, pz, qw, qx, qy, qz, ...",
                                                {"timestamp_ns", "px", "py", "pz", "qw", "qx", "qy", "qz"},
                                                true,
                                                true,
                                                0,
                                                true,
                                                true};

// EuRoC's header names p_RS_R_x; a headerless file has a comma-separated first data line of at
// least 8 fields whose time is an integer (nanoseconds). A time with a fraction is left to nobody:
// it is seconds, so not EuRoC, and detection refuses rather than drop the poses whose times round
// to the same nanosecond (issue 26: a TUM file with commas lost 2,969 of 3,000 poses that way).
bool sniff_euroc(const SniffLine& l) {
  if (l.comment) return l.text.find("p_RS_R_x") != std::string_view::npos;
  return l.commas && l.fields.size() >= 8 && format_impl::is_integer_text(l.fields[0]);
}

SourceTrace read_euroc(const std::string& path, const ImportOptions& options) {
  return format_impl::read_timed(path, options.read, kEurocLayout);
}

void write_euroc(const Trace& trace, const TraceTextSink& poses, const TraceTextSink*, const std::string& where) {
  format_impl::ChunkedText out(poses);
  format_impl::NanosecondTimes times(where, "euroc");
  // The dataset's header, its first 8 columns.
  fmt::format_to(out.out(), "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
                            "q_RS_y [], q_RS_z []\n");
  for (std::size_t i = 0; i < trace.poses.size(); ++i) {
    const Pose& p = trace.poses[i];
    std::string_view t;
    const std::int64_t ns = times.next(p.t_s, i, t);
    fmt::format_to(out.out(), FMT_COMPILE("{},{},{},{},{},{},{},{}\n"), ns, p.pos_m.x, p.pos_m.y, p.pos_m.z, p.q.w,
                   p.q.x, p.q.y, p.q.z);
    out.line_done();
  }
  out.flush();
}

}  // namespace

TraceFormat trace_format_euroc() {
  return {.name = "euroc",
          .why = "EuRoC MAV ground truth: 'timestamp, p x y z, q w x y z, ...' comma-separated, integer "
                 "nanoseconds; later columns ignored",
          .axes = {"z-up", "imu-urf"},
          .separate_times = false,
          .sniff_fields = ">= 8 comma-separated (an integer time)",
          .sniff = sniff_euroc,
          .read = read_euroc,
          .write = write_euroc,
          .time_unit_pow10 = -9};
}

}  // namespace vtsim
