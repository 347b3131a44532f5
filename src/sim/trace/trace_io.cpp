#include "sim/trace/trace_io.h"

#include <fmt/compile.h>
#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "sim/trace/trace_text.h"

namespace vtsim {

namespace {

constexpr std::string_view kMagic = "vtsim-trace";
constexpr std::string_view kVersion = "v1";
constexpr std::string_view kHeader = "t_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg";
constexpr std::string_view kFields[] = {"t_s", "x_m", "y_m", "z_m", "qw",
                                        "qx",  "qy",  "qz",  "vfov_deg"};
constexpr std::string_view kNamePrefix = "# name:";

bool header_matches(std::string_view line) {
  std::vector<std::string_view> f;
  trace_text::split_csv(line, f);
  if (f.size() != std::size(kFields)) return false;
  for (std::size_t i = 0; i < f.size(); ++i)
    if (f[i] != kFields[i]) return false;
  return true;
}

// What is wrong with a column header line, naming the missing or unexpected columns.
std::string header_error(std::string_view line) {
  std::vector<std::string_view> f;
  trace_text::split_csv(line, f);
  std::string missing, extra;
  for (std::string_view k : kFields)
    if (std::find(f.begin(), f.end(), k) == f.end()) missing += fmt::format("{}'{}'", missing.empty() ? "" : ", ", k);
  for (std::string_view k : f)
    if (std::find(std::begin(kFields), std::end(kFields), k) == std::end(kFields))
      extra += fmt::format("{}{}", extra.empty() ? "" : ", ", trace_text::quote(k));
  std::string why;
  if (!missing.empty()) why = "lacks " + missing;
  if (!extra.empty()) why += (why.empty() ? "has " : "; has ") + extra;
  if (why.empty()) why = "has the columns in another order";
  return fmt::format("the column header {}: expected '{}'", why, kHeader);
}

// "# vtsim-trace v1 image_width=W image_height=H"
void parse_magic(std::string_view line, const std::string& where, Trace& trace) {
  std::string_view body = trace_text::trim(line);
  std::vector<std::string_view> tok;
  if (!body.empty() && body.front() == '#') {
    body.remove_prefix(1);
    trace_text::split_ws(body, tok);
  }
  if (tok.empty() || tok[0] != kMagic)
    throw InputError(where, fmt::format("not a native trace: the first line must be '# {} {} "
                                        "image_width=W image_height=H'",
                                        kMagic, kVersion));
  if (tok.size() < 2 || tok[1] != kVersion)
    throw InputError(where, fmt::format("unsupported native trace version {} (this build reads {})",
                                        trace_text::quote(tok.size() < 2 ? "" : tok[1]), kVersion));
  bool have_w = false, have_h = false;
  for (std::size_t i = 2; i < tok.size(); ++i) {
    const std::size_t eq = tok[i].find('=');
    const std::string_view key = tok[i].substr(0, eq);
    const std::string_view val = eq == std::string_view::npos ? "" : tok[i].substr(eq + 1);
    if (key == "image_width" && !have_w) {
      trace.image_width = trace_text::parse_int(val, 1, kMaxImageSide, where, key);
      have_w = true;
    } else if (key == "image_height" && !have_h) {
      trace.image_height = trace_text::parse_int(val, 1, kMaxImageSide, where, key);
      have_h = true;
    } else {
      throw InputError(where, fmt::format("unknown or repeated header key {}", trace_text::quote(key)));
    }
  }
  if (!have_w || !have_h)
    throw InputError(where, "the header must give image_width=W and image_height=H");
}

void check_pose_ranges(const Pose& p, const std::string& where) {
  if (std::abs(p.t_s) > kMaxAbsTime_s)
    throw InputError(where, fmt::format("time {} s is not within +-{:g} s", p.t_s, kMaxAbsTime_s));
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(p.pos_m[k]) || std::abs(p.pos_m[k]) > kMaxAbsCoordinate_m)
      throw InputError(where, fmt::format("coordinate {} = {} m is not within +-{:g} m", "xyz"[k],
                                          p.pos_m[k], kMaxAbsCoordinate_m));
  if (!(p.vfov_deg >= kMinVfov_deg && p.vfov_deg <= kMaxVfov_deg))
    throw InputError(where, fmt::format("vfov_deg {} is outside [{}, {}]", p.vfov_deg, kMinVfov_deg, kMaxVfov_deg));
}

}  // namespace

Trace load_trace(const std::string& path, const TraceReadOptions& options, TraceLoadReport* report) {
  trace_text::LineReader in(path, options.limits);
  Trace trace;
  TraceRepairs repairs;
  std::string_view line;
  if (!in.next(line)) throw InputError(at_line(path, 1), "empty file (no header, no poses)");
  parse_magic(line, in.where(), trace);
  trace.poses.reserve(in.expected_lines(100));  // a generated pose line is 60-140 bytes

  bool have_header = false, have_name = false;
  std::vector<std::string_view> f;
  std::int64_t prev_line = 0;
  while (in.next(line)) {
    if (trace_text::is_blank(line)) continue;
    if (trace_text::is_comment(line)) {
      const std::string_view t = trace_text::trim(line);
      if (!have_header && !have_name && t.substr(0, kNamePrefix.size()) == kNamePrefix) {
        trace.name = std::string(trace_text::trim(t.substr(kNamePrefix.size())));
        have_name = true;
      }
      continue;
    }
    if (!have_header) {
      if (!header_matches(line)) throw InputError(in.where(), header_error(line));
      have_header = true;
      continue;
    }
    const std::string where = in.where();
    trace_text::split_csv(line, f);
    if (f.size() != std::size(kFields))
      throw InputError(where, fmt::format("expected {} fields ({}), found {}", std::size(kFields),
                                          kHeader, f.size()));
    double v[std::size(kFields)];
    for (std::size_t i = 0; i < f.size(); ++i) v[i] = trace_text::parse_double(f[i], where, kFields[i]);
    Pose p;
    p.t_s = v[0];
    p.pos_m = {v[1], v[2], v[3]};
    p.q = glm::dquat(v[4], v[5], v[6], v[7]);
    p.vfov_deg = v[8];
    check_pose_ranges(p, where);
    trace_text::check_quat(p.q, where, options.strict, repairs);
    if (!trace.poses.empty()) {
      const double prev = trace.poses.back().t_s;
      if (p.t_s < prev)
        throw InputError(where, fmt::format("time goes backwards: t_s {} after {} (line {})", p.t_s,
                                            prev, prev_line));
      if (p.t_s == prev) {
        if (options.strict)
          throw InputError(where, fmt::format("duplicate time t_s {} (line {}) (strict mode)", p.t_s,
                                              prev_line));
        ++repairs.duplicate_times_dropped;
        continue;
      }
    }
    trace.poses.push_back(p);
    prev_line = in.line_no();
  }
  if (!have_header)
    throw InputError(in.where(), fmt::format("no column header '{}' and no poses", kHeader));
  if (trace.poses.empty()) throw InputError(in.where(), "no poses after the column header");
  if (!have_name) trace.name = trace_text::sanitize_line(path);
  check_repairs(repairs, static_cast<std::int64_t>(trace.poses.size()) + repairs.dropped(), path,
                options.allow_repairs);
  if (report) {
    report->format = "native";
    report->lines = in.line_no();
    report->poses = static_cast<std::int64_t>(trace.poses.size());
    report->repairs = repairs;
  }
  return trace;
}

void check_repairs(const TraceRepairs& repairs, std::int64_t poses_read, const std::string& path,
                   bool allow_repairs) {
  const std::int64_t dropped = repairs.dropped();
  if (allow_repairs || dropped <= kMaxDroppedPoses ||
      static_cast<double>(dropped) <= kMaxDroppedFraction * static_cast<double>(poses_read))
    return;
  throw InputError(path, fmt::format("{} of {} poses dropped ({} with a repeated time): more than {} pose and "
                                     "more than {:g} %, so the times are probably misread (a wrong --format or time unit); "
                                     "check them, or give --allow-repairs (a sweep spec: allow_repairs = true) to keep the {} poses left",
                                     dropped, poses_read, repairs.duplicate_times_dropped, kMaxDroppedPoses,
                                     kMaxDroppedFraction * 100, poses_read - dropped));
}

std::vector<std::string> repair_warnings(const TraceRepairs& r, std::int64_t poses_read, const std::string& path) {
  std::vector<std::string> out;
  const auto add = [&](std::int64_t n, std::string_view one, std::string_view many, std::string_view what) {
    if (n > 0) out.push_back(fmt::format("{}: {} {} {} (of {} poses read)", path, n, n == 1 ? one : many, what, poses_read));
  };
  add(r.duplicate_times_dropped, "pose", "poses", "with a repeated time dropped");
  add(r.quats_renormalised, "quaternion", "quaternions", "renormalised");
  add(r.rotations_orthonormalised, "rotation", "rotations", "orthonormalised");
  return out;
}

void validate_trace(const Trace& trace, const std::string& where) {
  if (trace.image_width < 1 || trace.image_width > kMaxImageSide || trace.image_height < 1 ||
      trace.image_height > kMaxImageSide)
    throw InputError(where, fmt::format("image size {}x{} is outside [1, {}] per side",
                                        trace.image_width, trace.image_height, kMaxImageSide));
  if (trace.poses.empty()) throw InputError(where, "the trace has no poses");
  for (std::size_t i = 0; i < trace.poses.size(); ++i) {
    const Pose& p = trace.poses[i];
    const auto w = [&] { return fmt::format("{} pose {}", where, i); };  // only on error
    if (!std::isfinite(p.t_s)) throw InputError(w(), "time is not finite");
    bool in_range = std::abs(p.t_s) <= kMaxAbsTime_s && p.vfov_deg >= kMinVfov_deg && p.vfov_deg <= kMaxVfov_deg;
    for (int k = 0; k < 3; ++k) in_range = in_range && std::abs(p.pos_m[k]) <= kMaxAbsCoordinate_m;
    if (!in_range) check_pose_ranges(p, w());
    if (i > 0 && !(p.t_s > trace.poses[i - 1].t_s))
      throw InputError(w(), fmt::format("time {} s does not increase (previous {} s)", p.t_s,
                                        trace.poses[i - 1].t_s));
    const double n2 = p.q.w * p.q.w + p.q.x * p.q.x + p.q.y * p.q.y + p.q.z * p.q.z;
    if (!std::isfinite(n2) || !(std::abs(std::sqrt(n2) - 1.0) <= kQuatUnitTolerance))
      throw InputError(w(), fmt::format("quaternion norm {} is not unit", std::sqrt(n2)));
  }
}

namespace {

// Formats the native text in chunks of about 64 KiB handed to sink(data, size): a long trace is
// written without building its whole text in memory.
template <class Sink>
void emit_native(const Trace& trace, Sink&& sink) {
  fmt::memory_buffer out;
  auto it = std::back_inserter(out);
  fmt::format_to(it, "# {} {} image_width={} image_height={}\n", kMagic, kVersion,
                 trace.image_width, trace.image_height);
  if (!trace.name.empty()) fmt::format_to(it, "{} {}\n", kNamePrefix, trace_text::sanitize_line(trace.name));
  fmt::format_to(it, "{}\n", kHeader);
  // fmt's "{}" for double is the shortest string that reads back to the same bits.
  for (const Pose& p : trace.poses) {
    fmt::format_to(it, FMT_COMPILE("{},{},{},{},{},{},{},{},{}\n"), p.t_s, p.pos_m.x, p.pos_m.y,
                   p.pos_m.z, p.q.w, p.q.x, p.q.y, p.q.z, p.vfov_deg);
    if (out.size() >= 64 * 1024) {
      sink(out.data(), out.size());
      out.clear();
    }
  }
  sink(out.data(), out.size());
}

}  // namespace

std::string format_trace(const Trace& trace) {
  std::string s;
  s.reserve(200 + trace.poses.size() * 160);  // a pose line is at most ~9 * 24 bytes, often ~120
  emit_native(trace, [&](const char* d, std::size_t n) { s.append(d, n); });
  return s;
}

void write_trace_text(const Trace& trace, const std::function<void(std::string_view)>& sink) {
  emit_native(trace, [&](const char* d, std::size_t n) { sink(std::string_view(d, n)); });
}

void save_trace(const Trace& trace, const std::string& path) {
  validate_trace(trace, path);
  trace_text::TextFileOut out(path);
  emit_native(trace, [&](const char* d, std::size_t n) { out.write(std::string_view(d, n)); });
  out.close();
}

}  // namespace vtsim
