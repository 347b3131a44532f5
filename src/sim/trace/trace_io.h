#pragma once
// The native trace format (read + write) and the checks every trace passes (docs/traces.md).
//
//   # vtsim-trace v1 image_width=1920 image_height=1080
//   # name: walk speed=1.5 heading=0 ...
//   t_s,x_m,y_m,z_m,qw,qx,qy,qz,vfov_deg
//   0,4096,4096,1.7,0.99144486137381038,0,0.13052619222005157,0,60
//
// Doubles are written in their shortest round-trip form, so save -> load is bit-exact.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "core/trace.h"

namespace vtsim {

// Sanity limits for untrusted trace files. The defaults leave room for a day at 60 Hz (5.2 M
// lines, about 0.6 GB of native CSV) while refusing a 64 KiB line or a runaway file.
struct TraceReadLimits {
  std::uint64_t max_file_bytes = std::uint64_t{1} << 30;  // bytes (1 GiB)
  std::size_t max_line_bytes = 64 * 1024;                 // bytes, without the line terminator
};

// Documented repairs a reader made instead of failing; each is counted (and each is an error
// under TraceReadOptions::strict). Callers print them (repair_warnings); a reader refuses a file
// whose repairs dropped more poses than check_repairs allows.
struct TraceRepairs {
  std::int64_t quats_renormalised = 0;       // | |q| - 1 | <= 1e-3 but more than 1e-6 and more than
                                             // the rounding of the printed digits explains: q / |q| used
  std::int64_t duplicate_times_dropped = 0;  // a pose with the same time as the one before: dropped
  std::int64_t rotations_orthonormalised = 0;  // KITTI 3x3 block off orthonormal by (1e-6, 1e-3]
  std::int64_t total() const {
    return quats_renormalised + duplicate_times_dropped + rotations_orthonormalised;
  }
  std::int64_t dropped() const { return duplicate_times_dropped; }  // poses read but not kept
};

struct TraceReadOptions {
  TraceReadLimits limits;
  bool strict = false;         // turn every repair into an InputError
  bool allow_repairs = false;  // keep a file whose repairs dropped more than check_repairs allows
};

// What a reader saw, for `trace info` and the import summary.
struct TraceLoadReport {
  std::string format;        // "native", "tum", "euroc", "kitti"
  std::int64_t lines = 0;    // lines read, including comments and blank lines
  std::int64_t poses = 0;    // poses kept
  TraceRepairs repairs;
};

// The repair policy (docs/traces.md, "Errors and repairs"): a reader may drop at most
// kMaxDroppedPoses poses or kMaxDroppedFraction of the poses it read, whichever is more. One
// doubled time stamp is the usual harmless glitch of a recorder (a frame sent twice); more than 1 %
// dropped means the times are being misread (the wrong format or unit: issue 26 saw 2,969 of 3,000
// poses dropped from a TUM file read as EuRoC), so the file is refused unless allow_repairs.
inline constexpr std::int64_t kMaxDroppedPoses = 1;
inline constexpr double kMaxDroppedFraction = 0.01;

// Throws InputError(path, "N of M poses dropped (...) ...; give --allow-repairs ...") when
// repairs.dropped() is beyond the policy above and allow_repairs is false. poses_read counts the
// poses kept plus those dropped.
void check_repairs(const TraceRepairs& repairs, std::int64_t poses_read, const std::string& path,
                   bool allow_repairs);

// One line per kind of repair made, naming the file and the count: "walk.csv: 1 pose with a
// repeated time dropped (of 1202 read)". Empty when there was none. For the CLI's warnings.
std::vector<std::string> repair_warnings(const TraceRepairs& repairs, std::int64_t poses_read,
                                         const std::string& path);

// Tolerances shared by all readers and by validate_trace.
inline constexpr double kQuatUnitTolerance = 1e-9;   // what validate_trace accepts as unit; readers
                                                     // keep such a q bit-exact (round trips)
inline constexpr double kQuatNormSilent = 1e-6;      // up to this (or to what the rounding of the
                                                     // printed digits explains), not counted
inline constexpr double kQuatNormTolerance = 1e-3;   // beyond this a quaternion is an error
inline constexpr double kMaxAbsCoordinate_m = 1e10;  // ~1500 Earth radii: keeps squared distances
                                                     // finite and planet-scale worlds legal
inline constexpr double kMaxAbsTime_s = 4e9;         // ~127 years: int64 nanosecond ticks reach 9.2e9 s, and a
                                                     // replay adds latencies and its pacing on top

// Reads a native trace. Throws InputError("path:line", ...) on any malformed input; repairs per
// TraceRepairs (counted in *report when given).
Trace load_trace(const std::string& path, const TraceReadOptions& options = {},
                 TraceLoadReport* report = nullptr);

// The native text of a trace (validate_trace first). Shortest round-trip doubles.
std::string format_trace(const Trace& trace);

// The same text handed to sink in order, in chunks of about 64 KiB (no validation): a long trace is
// written without building its whole text in memory.
void write_trace_text(const Trace& trace, const std::function<void(std::string_view)>& sink);

// Writes format_trace(trace) to path ("-" = stdout). Throws InputError(path, ...) if the trace
// is invalid or the file cannot be written.
void save_trace(const Trace& trace, const std::string& path);

// Checks the invariants every consumer may rely on: at least one pose; finite values; times
// strictly increasing and |t| <= kMaxAbsTime_s; |coordinates| <= kMaxAbsCoordinate_m;
// | |q| - 1 | <= kQuatUnitTolerance; vfov in [kMinVfov_deg, kMaxVfov_deg]; image sides in [1, kMaxImageSide].
// Throws InputError(where + " pose i", ...) naming the first offending pose (0-based).
void validate_trace(const Trace& trace, const std::string& where);

}  // namespace vtsim
