#pragma once
// What a trace contains, for `vtsim trace info` and for checking imports (docs/traces.md,
// "Inspect"). One pass over the poses plus a sort of the segment speeds: O(n log n).
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>
#include <nlohmann/json_fwd.hpp>

#include "core/trace.h"

namespace vtsim {

struct TraceStatsOptions {
  double cut_speed_mps = 1000.0;  // a segment faster than this (and longer than cut_distance_m)
  double cut_distance_m = 10.0;   // is a cut: the camera jumped. 1000 m/s is 10x the flight trace
                                  // and beyond any camera we simulate; 10 m keeps jitter over a
                                  // tiny time step from counting.
  double gap_s = 0.5;             // a time step longer than this is a gap (as in resampling)
  double min_step_s = 0.002;      // speeds are measured over steps at least this long: shorter
                                  // steps merge with the next. TUM fr2_desk has 0.1 ms steps and
                                  // 0.1 mm position digits, i.e. 1 m/s of pure quantisation noise
                                  // per step; real camera rates are <= 500 Hz (2 ms). 0: raw steps.
  std::size_t max_listed = 20;    // cuts and gaps listed individually (all are counted)
};

struct TraceEvent {
  std::int64_t pose = 0;   // index of the pose after the jump or gap
  double t_s = 0.0;        // its time, seconds
  double distance_m = 0.0; // distance from the previous pose, metres
  double dt_s = 0.0;       // time from the previous pose, seconds
};

// Segments are consecutive pose pairs. Cut segments are excluded from the path length and the
// speed and angular-speed figures (they are reported as cuts instead). Speeds and angular speeds
// are measured over speed steps: runs of consecutive non-cut segments at least min_step_s long
// (a step ends at the first pose min_step_s or more after its start, or before a cut; a final
// shorter run counts only if it is the only one).
struct TraceStats {
  std::int64_t frames = 0;            // poses
  double duration_s = 0.0;            // t_last - t_first
  double mean_rate_hz = 0.0;          // (frames - 1) / duration (0 for one pose)
  double dt_min_s = 0.0, dt_max_s = 0.0;  // shortest and longest time step, seconds
  double path_length_m = 0.0;         // sum of segment lengths, cuts excluded
  double speed_p50_mps = 0.0;         // step speeds |p_end - p_start| / dt, nearest-rank percentiles
  double speed_p99_mps = 0.0;
  double speed_max_mps = 0.0;
  double angular_speed_max_dps = 0.0; // max over steps of (rotation angle between the ends) / dt
  std::int64_t speed_steps = 0;       // how many steps the speed figures are over
  glm::dvec3 bbox_min_m{0.0}, bbox_max_m{0.0};  // of all positions, world metres
  double vfov_min_deg = 0.0, vfov_max_deg = 0.0;
  std::int64_t cuts = 0;              // segments classified as cuts (TraceStatsOptions)
  double cut_distance_max_m = 0.0;    // the longest jump
  std::vector<TraceEvent> cut_list;   // the first max_listed cuts
  std::int64_t gaps = 0;              // time steps longer than gap_s
  std::vector<TraceEvent> gap_list;   // the first max_listed gaps
  int image_width = 0, image_height = 0;
};

// The trace must satisfy validate_trace (throws InputError otherwise).
TraceStats trace_stats(const Trace& trace, const TraceStatsOptions& options = {});

nlohmann::json to_json(const TraceStats& s);

// Rotation angle between two unit quaternions, radians in [0, pi]; q and -q are the same rotation.
double rotation_angle(const glm::dquat& a, const glm::dquat& b);

}  // namespace vtsim
