#include "sim/trace/impl/format_common.h"

#include <fmt/compile.h>
#include <fmt/core.h>

#include <glm/gtc/quaternion.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <vector>

#include "core/error.h"

namespace vtsim::format_impl {

namespace {

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

}  // namespace

bool is_integer_text(std::string_view tok) {
  if (!tok.empty() && (tok[0] == '+' || tok[0] == '-')) tok.remove_prefix(1);
  const std::size_t e = tok.find_first_of("eE");
  std::string_view mant = tok.substr(0, e);
  long exp = 0;
  if (e != std::string_view::npos) {
    std::string_view x = tok.substr(e + 1);
    if (!x.empty() && x[0] == '+') x.remove_prefix(1);
    const auto [p, ec] = std::from_chars(x.data(), x.data() + x.size(), exp);
    if (x.empty() || ec != std::errc() || p != x.data() + x.size()) return false;
  }
  const std::size_t dot = mant.find('.');
  std::string_view frac = dot == std::string_view::npos ? std::string_view() : mant.substr(dot + 1);
  const std::string_view whole = mant.substr(0, dot);
  while (!frac.empty() && frac.back() == '0') frac.remove_suffix(1);
  const auto digits = [](std::string_view d) {
    return std::all_of(d.begin(), d.end(), [](char c) { return c >= '0' && c <= '9'; });
  };
  return !mant.empty() && mant != "." && digits(whole) && digits(frac) && static_cast<long>(frac.size()) <= exp;
}

void check_position(const glm::dvec3& p, const std::string& where) {
  for (int k = 0; k < 3; ++k)
    if (std::abs(p[k]) > kMaxAbsCoordinate_m)
      throw InputError(where, fmt::format("coordinate {} = {} m is not within +-{:g} m", "xyz"[k], p[k],
                                          kMaxAbsCoordinate_m));
}

void wrong_field_count(const std::string& where, std::size_t want, std::size_t got, std::string_view layout,
                       bool at_least) {
  throw InputError(where, fmt::format("expected {}{} fields ({}), found {}", at_least ? "at least " : "",
                                      want, layout, got));
}

void finish(const trace_text::LineReader& in, SourceTrace& s) {
  s.lines = in.line_no();
  if (s.trace.poses.empty())
    throw InputError(at_line(in.path(), std::max<std::int64_t>(in.line_no(), 1)),
                     in.line_no() == 0 ? "empty file (no poses)" : "no poses in the file");
}

SourceTrace read_timed(const std::string& path, const TraceReadOptions& ro, const TimedLayout& form) {
  trace_text::LineReader in(path, ro.limits);
  SourceTrace s;
  s.trace.poses.reserve(in.expected_lines(64));  // TUM lines are ~65 bytes, EuRoC ~170
  TimedSink sink(s, ro.strict);
  std::vector<std::string_view> f;
  std::string_view line;
  while (in.next(line)) {
    if (trace_text::is_blank(line) || trace_text::is_comment(line)) continue;
    const std::string where = in.where();
    if (form.csv || line.find(',') != std::string_view::npos) trace_text::split_csv(line, f);
    else trace_text::split_ws(line, f);
    if (form.extra_columns ? f.size() < 8 : f.size() != 8)
      wrong_field_count(where, 8, f.size(), form.layout, form.extra_columns);
    const std::int64_t t = trace_text::parse_time_ns(f[0], form.time_unit_pow10, where, form.names[0]);
    if (form.integer_time && !is_integer_text(f[0]))
      throw InputError(where, fmt::format("field '{}': {} is not an integer: {} times are integer nanoseconds, and "
                                          "these look like seconds; write them in nanoseconds (exactly, e.g. awk -F, -v "
                                          "OFS=, '!/^#/ {{ split($1, p, \".\"); $1 = p[1] substr(p[2] \"000000000\", 1, 9) "
                                          "}} 1' IN > OUT), or give --format tum for a TUM file with commas",
                                          form.names[0], trace_text::quote(f[0]), form.name));
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
  s.trace.name = trace_text::sanitize_line(fmt::format("{} {}", form.name, path));
  return s;
}

std::int64_t NanosecondTimes::next(double t_s, std::size_t i, std::string_view& text) {
  const char* end = fmt::format_to(text_, FMT_COMPILE("{}"), t_s);  // at most 24 characters
  text = std::string_view(text_, static_cast<std::size_t>(end - text_));
  // Cannot fail: a valid trace's |t| <= kMaxAbsTime_s is far inside the parser's range.
  const std::int64_t ns = trace_text::parse_time_ns(text, 9, where_, "t_s");
  if (i > 0 && ns == prev_ns_)
    throw InputError(fmt::format("{} pose {}", where_, i), fmt::format("time {} s is within half a nanosecond of the previous pose's ({} s): "
                                        "{} times resolve whole nanoseconds, so the pose would be dropped",
                                        t_s, prev_s_, format_));
  prev_ns_ = ns;
  prev_s_ = t_s;
  return ns;
}

}  // namespace vtsim::format_impl
