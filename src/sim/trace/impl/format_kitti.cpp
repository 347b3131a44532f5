// KITTI odometry poses (Geiger 2012; evo's "kitti"): 12 numbers per line, the row-major 3x4
// matrix [R | t] taking the left camera's optical frame to the first camera's (the world: x
// right, y down, z forward). The poses carry no time: KITTI keeps them in times.txt (one time in
// seconds per pose), or they come from a fixed rate (KITTI odometry is 10 Hz).
#include <fmt/compile.h>
#include <fmt/core.h>

#include <glm/gtc/quaternion.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "sim/trace/impl/format_common.h"
#include "sim/trace/trace_import.h"

namespace vtsim {

namespace {

// A whitespace-separated first data line of 12 fields.
bool sniff_kitti(const SniffLine& l) { return !l.comment && !l.commas && l.fields.size() == 12; }

// Times come from opt.kitti_times_path (one value in seconds per pose) or opt.kitti_rate_hz.
SourceTrace read_kitti(const std::string& path, const ImportOptions& opt) {
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
    if (f.size() != 12)
      format_impl::wrong_field_count(where, 12, f.size(), "r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz");
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
    format_impl::check_position(p, where);
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
  format_impl::finish(in, s);
  s.trace.name = trace_text::sanitize_line(fmt::format("kitti {}", path));
  const std::size_t n = s.trace.poses.size();

  if (have_rate) {
    for (std::size_t i = 0; i < n; ++i) s.trace.poses[i].t_s = static_cast<double>(i) / opt.kitti_rate_hz;
    s.t0_s = 0.0;
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
    if (tf.size() != 1) format_impl::wrong_field_count(where, 1, tf.size(), "time in seconds");
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

// The times, when asked for, as KITTI's times.txt (first: a pose the times cannot give back fails
// before any pose is written); then the rows of R = mat3_cast(q) with t.
void write_kitti(const Trace& trace, const TraceTextSink& poses, const TraceTextSink* times, const std::string& where) {
  if (times) {
    format_impl::ChunkedText tout(*times);
    format_impl::NanosecondTimes ns(where, "kitti");
    for (std::size_t i = 0; i < trace.poses.size(); ++i) {
      std::string_view t;
      ns.next(trace.poses[i].t_s, i, t);
      fmt::format_to(tout.out(), FMT_COMPILE("{}\n"), t);
      tout.line_done();
    }
    tout.flush();
  }
  format_impl::ChunkedText out(poses);
  for (const Pose& p : trace.poses) {
    const glm::dmat3 r = glm::mat3_cast(p.q);  // r[col][row]
    fmt::format_to(out.out(), FMT_COMPILE("{} {} {} {} {} {} {} {} {} {} {} {}\n"), r[0][0], r[1][0], r[2][0],
                   p.pos_m.x, r[0][1], r[1][1], r[2][1], p.pos_m.y, r[0][2], r[1][2], r[2][2], p.pos_m.z);
    out.line_done();
  }
  out.flush();
}

}  // namespace

TraceFormat trace_format_kitti() {
  return {.name = "kitti",
          .why = "KITTI odometry poses: 12 numbers, the row-major 3x4 [R | t] (camera -> world); times from a "
                 "separate file or a rate",
          .axes = {"y-down", "optical"},
          .separate_times = true,
          .sniff_fields = "12",
          .sniff = sniff_kitti,
          .read = read_kitti,
          .write = write_kitti,
          .time_unit_pow10 = 0};
}

}  // namespace vtsim
