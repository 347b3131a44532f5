#include "sim/trace/trace_import.h"

#include <fmt/core.h>

#include <algorithm>
#include <fstream>
#include <string_view>
#include <stdexcept>
#include <vector>

#include "core/error.h"
#include "core/hash.h"
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
    std::string rules;  // "tum has 8, kitti 12, euroc >= 8 comma-separated"
    for (const TraceFormat& e : formats.entries()) {
      if (e.sniff_fields.empty()) continue;
      rules += fmt::format("{}{}{} {}", rules.empty() ? "" : ", ", e.name, rules.empty() ? " has" : "", e.sniff_fields);
    }
    throw InputError(in.where(), fmt::format("cannot tell the trace format from this line ({} fields: {}); "
                                             "give the format",
                                             f.size(), rules));
  }
  throw InputError(at_line(path, std::max<std::int64_t>(in.line_no(), 1)),
                   in.line_no() == 0 ? "empty file (no poses)" : "no poses in the file");
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
