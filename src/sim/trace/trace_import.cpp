#include "sim/trace/trace_import.h"

#include <fmt/core.h>

#include <glm/gtc/quaternion.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "sim/trace/trace_text.h"

namespace vtsim {

namespace {

// A trace in its source conventions, times relative to the first pose.
struct SourceTrace {
  Trace trace;
  double t0_s = 0.0;  // absolute time of the first pose, seconds (for rebase_time = false)
  std::int64_t lines = 0;
  TraceRepairs repairs;
};

void check_position(const glm::dvec3& p, const std::string& where) {
  for (int k = 0; k < 3; ++k)
    if (std::abs(p[k]) > kMaxAbsCoordinate_m)
      throw InputError(where, fmt::format("coordinate {} = {} m is not within +-{:g} m", "xyz"[k], p[k],
                                          kMaxAbsCoordinate_m));
}

// Appends poses with integer-nanosecond source times: rejects time going backwards, drops (and
// counts) a repeated time, keeps the first time for rebasing.
class TimedSink {
 public:
  TimedSink(SourceTrace& out, bool strict) : out_(out), strict_(strict) {}

  void add(std::int64_t t_ns, const glm::dvec3& p, const glm::dquat& q, const std::string& where,
           std::int64_t line) {
    if (out_.trace.poses.empty()) {
      t0_ns_ = t_ns;
      out_.t0_s = static_cast<double>(t_ns) / 1e9;
    } else {
      if (t_ns < prev_ns_)
        throw InputError(where, fmt::format("time goes backwards: {:.9f} s after {:.9f} s (line {})",
                                            static_cast<double>(t_ns) / 1e9,
                                            static_cast<double>(prev_ns_) / 1e9, prev_line_));
      if (t_ns == prev_ns_) {
        if (strict_)
          throw InputError(where, fmt::format("duplicate time {:.9f} s (line {}) (strict mode)",
                                              static_cast<double>(t_ns) / 1e9, prev_line_));
        ++out_.repairs.duplicate_times_dropped;
        return;
      }
    }
    std::int64_t rel = 0;
    if (__builtin_sub_overflow(t_ns, t0_ns_, &rel))
      throw InputError(where, "time span of the trace is out of range");
    Pose pose;
    pose.t_s = static_cast<double>(rel) / 1e9;
    pose.pos_m = p;
    pose.q = q;
    out_.trace.poses.push_back(pose);
    prev_ns_ = t_ns;
    prev_line_ = line;
  }

 private:
  SourceTrace& out_;
  bool strict_;
  std::int64_t t0_ns_ = 0, prev_ns_ = 0, prev_line_ = 0;
};

[[noreturn]] void wrong_field_count(const std::string& where, std::size_t want, std::size_t got,
                                    std::string_view layout, bool at_least = false) {
  throw InputError(where, fmt::format("expected {}{} fields ({}), found {}", at_least ? "at least " : "",
                                      want, layout, got));
}

void finish(const trace_text::LineReader& in, SourceTrace& s) {
  s.lines = in.line_no();
  if (s.trace.poses.empty())
    throw InputError(at_line(in.path(), std::max<std::int64_t>(in.line_no(), 1)),
                     in.line_no() == 0 ? "empty file (no poses)" : "no poses in the file");
}

// The two timestamped text formats: a time, a position and a quaternion on each line.
struct TimedFormat {
  std::string_view layout;       // for the field-count error
  std::string_view names[8];     // per field, for parse errors
  bool csv = false;              // comma-separated (EuRoC) or whitespace-separated (TUM)
  bool extra_columns = false;    // more than 8 fields allowed (ignored)
  int time_unit_pow10 = 0;       // the time unit is 10^k ns (9: seconds, 0: nanoseconds)
  bool w_first = false;          // quaternion w x y z (EuRoC) or x y z w (TUM)
};

// TUM RGB-D: "timestamp tx ty tz qx qy qz qw", seconds and metres, '#' comments.
constexpr TimedFormat kTum{"timestamp tx ty tz qx qy qz qw", {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"},
                           false, false, 9, false};
// EuRoC MAV ground truth: "timestamp[ns], p x y z [m], q w x y z, ..." extra columns ignored.
constexpr TimedFormat kEuroc{"timestamp_ns, px, py, pz, qw, qx, qy, qz, ...",
                             {"timestamp_ns", "px", "py", "pz", "qw", "qx", "qy", "qz"}, true, true, 0, true};

SourceTrace parse_timed(const std::string& path, const TraceReadOptions& ro, const TimedFormat& form) {
  trace_text::LineReader in(path, ro.limits);
  SourceTrace s;
  s.trace.poses.reserve(in.expected_lines(64));  // TUM lines are ~65 bytes, EuRoC ~170
  TimedSink sink(s, ro.strict);
  std::vector<std::string_view> f;
  std::string_view line;
  while (in.next(line)) {
    if (trace_text::is_blank(line) || trace_text::is_comment(line)) continue;
    const std::string where = in.where();
    if (form.csv) trace_text::split_csv(line, f);
    else trace_text::split_ws(line, f);
    if (form.extra_columns ? f.size() < 8 : f.size() != 8)
      wrong_field_count(where, 8, f.size(), form.layout, form.extra_columns);
    const std::int64_t t = trace_text::parse_time_ns(f[0], form.time_unit_pow10, where, form.names[0]);
    double v[8];
    for (int i = 1; i < 8; ++i) v[i] = trace_text::parse_double(f[static_cast<std::size_t>(i)], where, form.names[i]);
    const glm::dvec3 p(v[1], v[2], v[3]);
    check_position(p, where);
    glm::dquat q = form.w_first ? glm::dquat(v[4], v[5], v[6], v[7]) : glm::dquat(v[7], v[4], v[5], v[6]);
    double tol = 0.0;
    for (int i = 4; i < 8; ++i) tol += std::abs(v[i]) * trace_text::half_ulp_of_text(f[static_cast<std::size_t>(i)]);
    trace_text::check_quat(q, where, ro.strict, s.repairs, tol);
    sink.add(t, p, q, where, in.line_no());
  }
  finish(in, s);
  return s;
}

// KITTI odometry: 12 numbers per line, the row-major 3x4 matrix [R | t] (camera -> world).
// Times come from a times file (one value in seconds per pose) or a fixed rate.
SourceTrace parse_kitti(const std::string& path, const ImportOptions& opt) {
  const TraceReadOptions& ro = opt.read;
  const bool have_times = !opt.kitti_times_path.empty();
  const bool have_rate = opt.kitti_rate_hz != 0.0;
  if (have_times == have_rate)
    throw InputError(path, "KITTI poses carry no time: give a times file or a rate (exactly one; "
                           "KITTI odometry is 10 Hz)");
  if (have_rate && !(std::isfinite(opt.kitti_rate_hz) && opt.kitti_rate_hz > 0.0 &&
                     opt.kitti_rate_hz <= 1e6))
    throw InputError("rate", fmt::format("{} Hz is not in (0, 1e6]", opt.kitti_rate_hz));

  trace_text::LineReader in(path, ro.limits);
  SourceTrace s;
  std::vector<std::string_view> f;
  std::string_view line;
  while (in.next(line)) {
    if (trace_text::is_blank(line) || trace_text::is_comment(line)) continue;
    const std::string where = in.where();
    trace_text::split_ws(line, f);
    if (f.size() != 12) wrong_field_count(where, 12, f.size(), "r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz");
    double v[12];
    for (int i = 0; i < 12; ++i) {
      static constexpr std::string_view kNames[] = {"r11", "r12", "r13", "tx",  "r21", "r22",
                                                    "r23", "ty",  "r31", "r32", "r33", "tz"};
      v[i] = trace_text::parse_double(f[static_cast<std::size_t>(i)], where, kNames[i]);
    }
    glm::dmat3 r;  // glm is column-major: r[col][row]
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 3; ++col) r[col][row] = v[row * 4 + col];
    const glm::dvec3 p(v[3], v[7], v[11]);
    check_position(p, where);
    const glm::dmat3 e = glm::transpose(r) * r;
    double off = 0.0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) off = std::max(off, std::abs(e[i][j] - (i == j ? 1.0 : 0.0)));
    const double det = glm::determinant(r);
    if (off > kQuatNormTolerance || !(det > 0.0))
      throw InputError(where, fmt::format("the 3x3 block is not a rotation (|R^T R - I| = {:.3g}, "
                                          "det = {:.6g})",
                                          off, det));
    // Rounding of the printed entries alone moves R^T R by up to ~2 * sqrt(3) * half an ulp.
    double half_ulp = 0.0;
    for (int i = 0; i < 12; ++i)
      if (i % 4 != 3) half_ulp = std::max(half_ulp, trace_text::half_ulp_of_text(f[static_cast<std::size_t>(i)]));
    if (off > std::max(kQuatNormSilent, 4.0 * half_ulp)) {
      if (ro.strict)
        throw InputError(where, fmt::format("the 3x3 block is not orthonormal (|R^T R - I| = "
                                            "{:.3g}) (strict mode)",
                                            off));
      ++s.repairs.rotations_orthonormalised;
    }
    // The quaternion of R, normalised: the rotation nearest R to first order in R^T R - I.
    Pose pose;
    pose.pos_m = p;
    pose.q = glm::normalize(glm::quat_cast(r));
    s.trace.poses.push_back(pose);
  }
  finish(in, s);
  const std::size_t n = s.trace.poses.size();

  if (have_rate) {
    for (std::size_t i = 0; i < n; ++i) s.trace.poses[i].t_s = static_cast<double>(i) / opt.kitti_rate_hz;
    return s;
  }
  // Times file: one time per pose, in order, strictly increasing.
  trace_text::LineReader tin(opt.kitti_times_path, ro.limits);
  std::vector<std::string_view> tf;
  std::size_t i = 0;
  std::int64_t t0 = 0, prev = 0;
  while (tin.next(line)) {
    if (trace_text::is_blank(line) || trace_text::is_comment(line)) continue;
    const std::string where = tin.where();
    if (i == n)
      throw InputError(where, fmt::format("more times than poses ({} poses in {})", n, path));
    trace_text::split_ws(line, tf);
    if (tf.size() != 1) wrong_field_count(where, 1, tf.size(), "time in seconds");
    const std::int64_t t = trace_text::parse_time_ns(tf[0], 9, where, "time");
    if (i == 0) {
      t0 = t;
      s.t0_s = static_cast<double>(t) / 1e9;
    } else if (t <= prev) {
      throw InputError(where, fmt::format("time {:.9f} s does not increase (previous {:.9f} s)",
                                          static_cast<double>(t) / 1e9, static_cast<double>(prev) / 1e9));
    }
    std::int64_t rel = 0;
    if (__builtin_sub_overflow(t, t0, &rel)) throw InputError(where, "time span is out of range");
    s.trace.poses[i].t_s = static_cast<double>(rel) / 1e9;
    prev = t;
    ++i;
  }
  if (i != n)
    throw InputError(at_line(opt.kitti_times_path, std::max<std::int64_t>(tin.line_no(), 1)),
                     fmt::format("{} times for {} poses in {}", i, n, path));
  return s;
}

}  // namespace

std::string_view format_name(TraceFormat f) {
  switch (f) {
    case TraceFormat::native: return "native";
    case TraceFormat::tum: return "tum";
    case TraceFormat::euroc: return "euroc";
    case TraceFormat::kitti: return "kitti";
  }
  return "?";
}

TraceFormat parse_trace_format(std::string_view name, const std::string& where) {
  for (TraceFormat f : {TraceFormat::native, TraceFormat::tum, TraceFormat::euroc, TraceFormat::kitti})
    if (name == format_name(f)) return f;
  throw InputError(where, fmt::format("unknown trace format {} (native, tum, euroc, kitti)",
                                      trace_text::quote(name)));
}

FormatAxes default_axes(TraceFormat f) {
  switch (f) {
    case TraceFormat::native: return {"ENU", "FLU"};
    case TraceFormat::tum: return {"z-up", "optical"};
    case TraceFormat::euroc: return {"z-up", "imu-urf"};
    case TraceFormat::kitti: return {"y-down", "optical"};
  }
  return {"ENU", "FLU"};
}

TraceFormat detect_trace_format(const std::string& path, const TraceReadLimits& limits) {
  trace_text::LineReader in(path, limits);
  std::string_view line;
  std::vector<std::string_view> f;
  while (in.next(line)) {
    if (trace_text::is_blank(line)) continue;
    if (trace_text::is_comment(line)) {
      std::string_view body = trace_text::trim(line).substr(1);
      trace_text::split_ws(body, f);
      if (in.line_no() == 1 && !f.empty() && f[0] == "vtsim-trace") return TraceFormat::native;
      if (line.find("p_RS_R_x") != std::string_view::npos) return TraceFormat::euroc;
      continue;
    }
    if (line.find(',') != std::string_view::npos) {
      trace_text::split_csv(line, f);
      if (f.size() >= 8) return TraceFormat::euroc;
    } else {
      trace_text::split_ws(line, f);
      if (f.size() == 8) return TraceFormat::tum;
      if (f.size() == 12) return TraceFormat::kitti;
    }
    throw InputError(in.where(), fmt::format("cannot tell the trace format from this line ({} fields: "
                                             "tum has 8, kitti 12, euroc >= 8 comma-separated); "
                                             "give the format",
                                             f.size()));
  }
  throw InputError(at_line(path, std::max<std::int64_t>(in.line_no(), 1)),
                   in.line_no() == 0 ? "empty file (no poses)" : "no poses in the file");
}

Trace import_trace(const std::string& path, const ImportOptions& options, TraceLoadReport* report) {
  const TraceFormat format = options.format ? *options.format : detect_trace_format(path, options.read.limits);
  if (options.image_width < 0 || options.image_width > kMaxImageSide || options.image_height < 0 ||
      options.image_height > kMaxImageSide || (options.image_width == 0) != (options.image_height == 0))
    throw InputError("image", fmt::format("image size {}x{}: give both sides in [1, {}]",
                                          options.image_width, options.image_height, kMaxImageSide));
  SourceTrace s;
  switch (format) {
    case TraceFormat::native: {
      TraceLoadReport r;
      s.trace = load_trace(path, options.read, &r);
      s.lines = r.lines;
      s.repairs = r.repairs;
      break;
    }
    case TraceFormat::tum: s = parse_timed(path, options.read, kTum); break;
    case TraceFormat::euroc: s = parse_timed(path, options.read, kEuroc); break;
    case TraceFormat::kitti: s = parse_kitti(path, options); break;
  }
  if (format != TraceFormat::native) s.trace.name = trace_text::sanitize_line(fmt::format("{} {}", format_name(format), path));
  if (options.image_width > 0) {
    s.trace.image_width = options.image_width;
    s.trace.image_height = options.image_height;
  }
  TraceTransform tf = options.transform;
  const FormatAxes axes = default_axes(format);
  if (tf.world_axes.empty()) tf.world_axes = axes.world;
  if (tf.camera_axes.empty()) tf.camera_axes = axes.camera;
  if (!tf.rebase_time && format != TraceFormat::native) {
    // The source times are relative to t0 here (exact); absolute = t0 + rel, so
    // t' = rel * scale + (t0 * scale + offset).
    tf.time_offset_s += s.t0_s * tf.time_scale;
  }
  transform_trace(s.trace, tf, path);
  if (report) {
    report->format = std::string(format_name(format));
    report->lines = s.lines;
    report->poses = static_cast<std::int64_t>(s.trace.poses.size());
    report->repairs = s.repairs;
  }
  return s.trace;
}

Trace load_any_trace(const std::string& path, const TraceReadOptions& read, TraceLoadReport* report) {
  const TraceFormat format = detect_trace_format(path, read.limits);
  if (format == TraceFormat::native) return load_trace(path, read, report);
  ImportOptions o;
  o.format = format;
  o.read = read;
  return import_trace(path, o, report);
}

}  // namespace vtsim
