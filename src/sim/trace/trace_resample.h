#pragma once
// Resampling a trace to a fixed frame rate (docs/traces.md, "Resampling"): positions and vfov
// linearly, orientations by slerp along the shortest arc (Shoemake, "Animating rotation with
// quaternion curves", SIGGRAPH 1985), with a policy for gaps in the input.
#include <cstdint>

#include "core/trace.h"

namespace vtsim {

enum class GapPolicy {
  interpolate,  // interpolate across the gap like any other interval (smooth, invented motion)
  hold,         // hold the pose before the gap until the pose after it (a frozen camera, then a jump)
  error,        // refuse the trace (InputError naming the pose after the gap)
};

struct ResampleOptions {
  double fps = 60.0;     // output frames per second, (0, 10000]
  double gap_s = 0.5;    // an input interval longer than this (seconds) is a gap, > 0
  GapPolicy gap_policy = GapPolicy::interpolate;
};

struct ResampleReport {
  std::int64_t frames = 0;      // output poses
  std::int64_t gaps = 0;        // input intervals longer than gap_s
  double gap_time_s = 0.0;      // their total length, seconds
  double longest_gap_s = 0.0;   // the longest input interval (gap or not), seconds
};

// Largest trace resample() and the generators produce: 2e7 frames, 1.4 GB of poses, 3.9 days at 60 Hz.
inline constexpr std::int64_t kMaxTraceFrames = 20'000'000;

// Output frame k (k = 0..K) is at t_first + k / fps (closed form, no accumulated sum), where
// K = floor((t_last - t_first) * fps + 1e-6): the last frame is the last one not after t_last
// (within 1e-6 of a frame). Image size, name and source (path, hash) are kept. The input must satisfy validate_trace.
// Throws InputError for bad options, too many frames, or a gap under GapPolicy::error.
Trace resample(const Trace& in, const ResampleOptions& options, ResampleReport* report = nullptr);
inline Trace resample(const Trace& in, double fps) {
  ResampleOptions o;
  o.fps = fps;
  return resample(in, o);
}

// The pose at time t: the stored pose when t hits one exactly; linear / slerp between the two
// poses around t; the first or last pose outside the trace (clamped). O(log n). Gaps interpolate.
Pose sample_trace(const Trace& trace, double t_s);

// The part of a trace from from_s to to_s (seconds, the trace's own times, kept): the poses
// strictly inside, and a pose at each end, the stored one or sample_trace's interpolation. Image
// size, name and source are kept. Throws InputError("--from" / "--to", ...) unless
// t_first <= from_s < to_s <= t_last, both finite. The input must satisfy validate_trace.
Trace cut_trace(const Trace& in, double from_s, double to_s);

// Slerp from a (u = 0) to b (u = 1) along the shorter arc (b and -b are the same rotation); the
// angle comes from atan2, accurate for tiny and near-opposite rotations alike. Unit inputs.
glm::dquat slerp_shortest(const glm::dquat& a, const glm::dquat& b, double u);

}  // namespace vtsim
