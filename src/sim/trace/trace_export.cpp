#include "sim/trace/trace_export.h"

#include <fmt/core.h>

#include <cmath>
#include <optional>

#include "core/error.h"
#include "sim/trace/trace_format.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_text.h"
#include "sim/trace/trace_transform.h"

namespace vtsim {

namespace {

// What an import at rate_hz gives back (t_i = i / rate after the first pose) must be the trace's
// times to within half a nanosecond, the resolution of every other way times are written.
void check_export_rate(const Trace& trace, double rate_hz, const std::string& where) {
  if (!(std::isfinite(rate_hz) && rate_hz > 0.0 && rate_hz <= 1e6))
    throw InputError("rate", fmt::format("{} Hz is not in (0, 1e6]", rate_hz));
  const double t0 = trace.poses.front().t_s;
  for (std::size_t i = 0; i < trace.poses.size(); ++i) {
    const double want = static_cast<double>(i) / rate_hz;
    const double got = trace.poses[i].t_s - t0;
    if (!(std::abs(got - want) <= 0.5e-9))
      throw InputError(fmt::format("{} pose {}", where, i),
                       fmt::format("time {} s after the first pose is not {} / {} Hz = {} s: the rate does not "
                                   "give the times back (write a times file instead)",
                                   got, i, rate_hz, want));
  }
}

// "kitti": the formats whose poses carry no time.
std::string separate_times_names() {
  std::string s;
  for (const TraceFormat& f : trace_formats().entries())
    if (f.separate_times) s += (s.empty() ? "" : ", ") + std::string(f.name);
  return s;
}

}  // namespace

void export_trace(const Trace& trace, std::string_view format_name, const std::string& path,
                  const ExportOptions& options) {
  const TraceFormat& format = parse_trace_format(format_name, "format");
  const bool have_times = !options.times_path.empty(), have_rate = options.rate_hz != 0.0;
  if (!format.separate_times && (have_times || have_rate))
    throw InputError(have_times ? "times" : "rate",
                     fmt::format("{} poses carry their own times: a times file or a rate is for formats whose "
                                 "poses carry none ({})",
                                 format.name, separate_times_names()));
  if (format.separate_times && have_times == have_rate)
    throw InputError("times", fmt::format("{} poses carry no time: give a times file to write them to or the "
                                          "rate they are at (exactly one)",
                                          format.name));
  if (have_times && options.times_path == path)
    throw InputError("times", fmt::format("the times file {} is the poses' output too", options.times_path));
  validate_trace(trace, path);
  if (have_rate) check_export_rate(trace, options.rate_hz, path);

  Trace source = trace;
  to_source_axes(source, options.world_axes.empty() ? format.axes.world : options.world_axes,
                 options.camera_axes.empty() ? format.axes.camera : options.camera_axes, path);
  trace_text::TextFileOut out(path);
  std::optional<trace_text::TextFileOut> times_out;
  if (have_times) times_out.emplace(options.times_path);
  const TraceTextSink poses = [&](std::string_view s) { out.write(s); };
  const TraceTextSink times = [&](std::string_view s) { times_out->write(s); };
  format.write(source, poses, have_times ? &times : nullptr, path);
  out.close();
  if (times_out) times_out->close();
}

}  // namespace vtsim
