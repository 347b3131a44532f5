// Trace readers: the native CSV (trace_native) and the TUM / EuRoC / KITTI importers
// (trace_import). An accepted trace must also satisfy what the rest of vtsim assumes of it:
// validate_trace, a native round trip that keeps every pose bit for bit, statistics and resampling
// (which must succeed), and a transform (which may refuse).
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_targets.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_resample.h"
#include "sim/trace/trace_stats.h"
#include "sim/trace/trace_transform.h"

namespace vtsim::fuzz {

namespace {

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool same_pose(const Pose& a, const Pose& b) {
  return same_bits(a.t_s, b.t_s) && same_bits(a.pos_m.x, b.pos_m.x) && same_bits(a.pos_m.y, b.pos_m.y) &&
         same_bits(a.pos_m.z, b.pos_m.z) && same_bits(a.q.w, b.q.w) && same_bits(a.q.x, b.q.x) &&
         same_bits(a.q.y, b.q.y) && same_bits(a.q.z, b.q.z) && same_bits(a.vfov_deg, b.vfov_deg);
}

[[noreturn]] void fail(const char* target, const std::string& what) {
  std::fprintf(stderr, "vtsim fuzz %s: %s\n", target, what.c_str());
  std::abort();
}

// What every accepted trace goes through: validation, a strict native round trip, statistics and
// resampling must succeed; only the transform (which may move the trace out of range) may refuse.
void check_trace(const char* target, Trace& t) {
  must_succeed(target, "validate, round trip, stats, resample", [&] {
    validate_trace(t, "fuzz");
    const std::string text = format_trace(t);
    const std::string again_path = input_file(reinterpret_cast<const std::uint8_t*>(text.data()), text.size(), "rt.csv");
    const Trace again = load_trace(again_path, TraceReadOptions{{}, true});
    if (again.poses.size() != t.poses.size() || again.image_width != t.image_width || again.image_height != t.image_height)
      fail(target, "native round trip changed the trace's size");
    for (std::size_t k = 0; k < t.poses.size(); ++k)
      if (!same_pose(again.poses[k], t.poses[k])) fail(target, "native round trip changed pose " + std::to_string(k));
    (void)to_json(trace_stats(t));
    // At most ~1,000 output frames, whatever the duration.
    const double dur = t.poses.back().t_s - t.poses.front().t_s;
    ResampleOptions ro;
    ro.fps = dur > 0.0 ? std::min(60.0, 1000.0 / dur) : 60.0;
    if (ro.fps > 0.0) (void)resample(t, ro);
  });
  TraceTransform tf;
  tf.scale = 1000.0;
  tf.yaw_deg = 30.0;
  tf.recenter = true;
  tf.time_scale = 0.5;
  transform_trace(t, tf, "fuzz transform");
}

}  // namespace

void trace_native(const std::uint8_t* data, std::size_t size) {
  expect_accept_or_reject("trace_native", [&] {
    const std::string path = input_file(data, size, "csv");
    TraceLoadReport report;
    Trace t = load_trace(path, {}, &report);
    check_trace("trace_native", t);
  });
  expect_accept_or_reject("trace_native", [&] { (void)load_trace(input_file(data, size, "csv"), TraceReadOptions{{}, true}); });
}

// First part: the trajectory; the part after a 0xFF byte, when present, is a KITTI times file.
// The format is detected, then each explicit format is tried too.
void trace_import(const std::uint8_t* data, std::size_t size) {
  const auto parts = split2(data, size);
  const std::string_view poses = parts.first, times = parts.second;
  const std::string path = input_file(reinterpret_cast<const std::uint8_t*>(poses.data()), poses.size(), "txt");
  std::string times_path;
  if (!times.empty()) times_path = input_file(reinterpret_cast<const std::uint8_t*>(times.data()), times.size(), "times.txt");
  std::vector<std::string> formats = {""};  // detected, then each registered format
  for (const TraceFormat& e : trace_formats().entries()) formats.emplace_back(e.name);
  for (const std::string& f : formats) {
    expect_accept_or_reject("trace_import", [&] {
      ImportOptions o;
      o.format = f;
      if (times_path.empty()) o.kitti_rate_hz = 10.0;
      else o.kitti_times_path = times_path;
      TraceLoadReport report;
      Trace t = import_trace(path, o, &report);
      check_trace("trace_import", t);
    });
    expect_accept_or_reject("trace_import", [&] {  // strict: every repair is an error
      ImportOptions o;
      o.format = f;
      o.kitti_rate_hz = 10.0;
      o.read.strict = true;
      (void)import_trace(path, o);
    });
  }
}

}  // namespace vtsim::fuzz
