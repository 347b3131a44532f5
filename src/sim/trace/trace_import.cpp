#include "sim/trace/trace_import.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <string_view>
#include <stdexcept>
#include <vector>

#include "core/error.h"
#include "core/hash.h"
#include "sim/trace/impl/format_common.h"
#include "sim/trace/trace_text.h"

namespace vtsim {

const TraceFormat& parse_trace_format(std::string_view name, const std::string& where) {
  try {
    return trace_formats().at(name);
  } catch (const std::invalid_argument& e) {
    throw InputError(where, e.what());
  }
}

std::string detect_trace_format(const std::string& path, const TraceReadLimits& limits) {
  const Registry<TraceFormat>& formats = trace_formats();
  trace_text::LineReader in(path, limits);
  std::string_view line;
  std::vector<std::string_view> f;
  while (in.next(line)) {
    if (trace_text::is_blank(line)) continue;
    SniffLine l;
    l.line_no = in.line_no();
    l.text = line;
    l.comment = trace_text::is_comment(line);
    if (l.comment) {
      trace_text::split_ws(trace_text::trim(line).substr(1), f);
    } else {
      l.commas = line.find(',') != std::string_view::npos;
      if (l.commas) trace_text::split_csv(line, f);
      else trace_text::split_ws(line, f);
    }
    l.fields = f;
    for (const TraceFormat& e : formats.entries())
      if (e.sniff && e.sniff(l)) return std::string(e.name);
    if (l.comment) continue;
    if (l.commas && f.size() >= 8 && !format_impl::is_integer_text(f[0]) &&
        f[0].find_first_of(".eE") != std::string_view::npos)
      throw InputError(in.where(), fmt::format("cannot tell the trace format: a comma-separated line whose time {} "
                                               "has a fraction is not EuRoC (integer nanoseconds) nor TUM "
                                               "(whitespace-separated); give --format tum for a TUM file with commas, "
                                               "or write EuRoC times in seconds as nanoseconds",
                                               trace_text::quote(f[0])));
    std::string rules;  // "tum has 8, kitti 12, euroc >= 8 comma-separated"
    for (const TraceFormat& e : formats.entries()) {
      if (e.sniff_fields.empty()) continue;
      rules += fmt::format("{}{}{} {}", rules.empty() ? "" : ", ", e.name, rules.empty() ? " has" : "", e.sniff_fields);
    }
    throw InputError(in.where(), fmt::format("cannot tell the trace format from this line ({} fields: {}); "
                                             "give --format",
                                             f.size(), rules));
  }
  throw InputError(at_line(path, std::max<std::int64_t>(in.line_no(), 1)),
                   in.line_no() == 0 ? "empty file (no poses)" : "no poses in the file");
}

void check_time_units(std::int64_t poses, double span_s, int unit_pow10, double time_scale, std::string_view format,
                      const std::string& path) {
  if (poses < kTimeUnitCheckMinPoses) return;
  const double rate = span_s > 0.0 ? static_cast<double>(poses - 1) / span_s : HUGE_VAL;
  if (rate >= kMinPlausibleRate_hz && rate <= kMaxPlausibleRate_hz) return;
  const auto unit_name = [](int pow10) -> std::string {
    switch (pow10) {
      case -9: return "nanoseconds";
      case -6: return "microseconds";
      case -3: return "milliseconds";
      case 0: return "seconds";
      default: return fmt::format("1e{} s", pow10);
    }
  };
  // The power of ten that would put the rate in 1 Hz - 10 kHz (ms -> s: 3), if any.
  std::string fix;
  for (int k = -9; k <= 9 && std::isfinite(rate); k += 3) {
    const double r = rate / std::pow(10.0, k);
    if (k != 0 && r >= 1.0 && r <= 1e4) {
      fix = fmt::format("; if the times are in {} rather than {}, give --time-scale {:g}",
                        unit_name(unit_pow10 + k), unit_name(unit_pow10), time_scale * std::pow(10.0, k));
      break;
    }
  }
  if (fix.empty()) fix = "; check the file's time column (a duration of 0 s means every pose has the same time)";
  throw InputError(path, fmt::format("{} poses span {:.9g} s, a mean rate of {:.3g} Hz, far outside 1 Hz - 10 kHz: the "
                                     "times are probably not in {} as {} has them{}",
                                     poses, span_s, rate, unit_name(unit_pow10), format, fix));
}

Trace import_trace(const std::string& path, const ImportOptions& options, TraceLoadReport* report) {
  const TraceFormat& format = parse_trace_format(
      options.format.empty() ? detect_trace_format(path, options.read.limits) : options.format, "format");
  if (options.image_width < 0 || options.image_width > kMaxImageSide || options.image_height < 0 ||
      options.image_height > kMaxImageSide || (options.image_width == 0) != (options.image_height == 0))
    throw InputError("image", fmt::format("image size {}x{}: give both sides in [1, {}]",
                                          options.image_width, options.image_height, kMaxImageSide));
  SourceTrace s = format.read(path, options);
  if (options.image_width > 0) {
    s.trace.image_width = options.image_width;
    s.trace.image_height = options.image_height;
  }
  TraceTransform tf = options.transform;
  if (tf.world_axes.empty()) tf.world_axes = format.axes.world;
  if (tf.camera_axes.empty()) tf.camera_axes = format.axes.camera;
  if (!tf.rebase_time && s.t0_s) {
    // The source times are relative to t0 here (exact); absolute = t0 + rel, so
    // t' = rel * scale + (t0 * scale + offset).
    tf.time_offset_s += *s.t0_s * tf.time_scale;
  }
  transform_trace(s.trace, tf, path);
  const std::int64_t poses_read = static_cast<std::int64_t>(s.trace.poses.size()) + s.repairs.dropped();
  if (format.time_unit_pow10 && !(format.separate_times && options.kitti_rate_hz != 0.0))
    check_time_units(poses_read, s.trace.poses.back().t_s - s.trace.poses.front().t_s, *format.time_unit_pow10,
                     tf.time_scale, format.name, path);
  // The native reader applied the policy itself.
  if (format.name != "native") check_repairs(s.repairs, poses_read, path, options.read.allow_repairs);
  if (report) {
    report->format = std::string(format.name);
    report->lines = s.lines;
    report->poses = static_cast<std::int64_t>(s.trace.poses.size());
    report->repairs = s.repairs;
  }
  return s.trace;
}

namespace {

// FNV-1a 64 of a file's bytes, read in 1 MiB blocks; 0 when it cannot be read again (the loader
// has already reported what was wrong with it).
std::uint64_t trace_import_file_hash(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return 0;
  std::uint64_t h = fnv1a64({});
  std::vector<char> buf(1 << 20);
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    h = fnv1a64(std::string_view(buf.data(), static_cast<std::size_t>(in.gcount())), h);
  }
  return in.eof() ? h : 0;
}

}  // namespace

Trace load_any_trace(const std::string& path, const TraceReadOptions& read, TraceLoadReport* report) {
  const std::string format = detect_trace_format(path, read.limits);
  Trace t;
  if (format == "native") {
    t = load_trace(path, read, report);
  } else {
    ImportOptions o;
    o.format = format;
    o.read = read;
    t = import_trace(path, o, report);
  }
  t.source_path = path;
  t.source_hash = trace_import_file_hash(path);
  return t;
}

}  // namespace vtsim
