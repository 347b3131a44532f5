#pragma once
// Importing recorded trajectories (TUM RGB-D, EuRoC MAV ground truth, KITTI odometry poses; the
// formats of the evo trajectory tool) and format detection (docs/traces.md, "Importers").
#include <optional>
#include <string>
#include <string_view>

#include "core/trace.h"
#include "sim/trace/trace_io.h"
#include "sim/trace/trace_transform.h"

namespace vtsim {

enum class TraceFormat { native, tum, euroc, kitti };

std::string_view format_name(TraceFormat f);
// "native" | "tum" | "euroc" | "kitti"; throws InputError(where, ...) otherwise.
TraceFormat parse_trace_format(std::string_view name, const std::string& where);

// The source conventions a format's poses are in when the user does not say otherwise.
struct FormatAxes {
  const char* world;   // parse_world_axes spec
  const char* camera;  // parse_camera_axes spec
};
// native: ENU/FLU; tum: z-up/optical (the mocap frame; the colour camera's optical frame);
// euroc: z-up/imu-urf (the Vicon frame; the ground truth is the IMU body, x up, y right,
// z forward, within 1.5 degrees of cam0's optical axis); kitti: y-down/optical (the first
// camera's optical frame is the world).
FormatAxes default_axes(TraceFormat f);

// Looks at the first lines: "# vtsim-trace" -> native; a "p_RS_R_x" header or a comma-separated
// first data line with >= 8 fields -> euroc; a whitespace-separated first data line with 8 fields
// -> tum, with 12 -> kitti. Throws InputError("path:line", ...) when none fits.
TraceFormat detect_trace_format(const std::string& path, const TraceReadLimits& limits = {});

struct ImportOptions {
  std::optional<TraceFormat> format;  // nullopt: detect_trace_format
  std::string kitti_times_path;       // KITTI: a file with one time (s) per pose, or:
  double kitti_rate_hz = 0.0;         // KITTI: t_i = i / rate (10 Hz for KITTI odometry)
  TraceTransform transform;           // empty axis specs: default_axes(format)
  int image_width = 0;                // > 0: set the trace's image size (pixels); 0: keep the
  int image_height = 0;               // native file's, or 1920x1080 for the other formats
  TraceReadOptions read;
};

// Reads path in its format, then applies options.transform (trace_transform.h). Times are read
// as exact integer nanoseconds and rebased before conversion to double seconds, so a 2011 Unix
// time keeps its 0.1 ms digits. The result satisfies validate_trace.
Trace import_trace(const std::string& path, const ImportOptions& options = {},
                   TraceLoadReport* report = nullptr);

// Native files exactly as stored (load_trace); other formats through import_trace with defaults.
Trace load_any_trace(const std::string& path, const TraceReadOptions& read = {},
                     TraceLoadReport* report = nullptr);

}  // namespace vtsim
