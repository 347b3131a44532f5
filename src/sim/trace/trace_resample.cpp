#include "sim/trace/trace_resample.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "sim/trace/trace_io.h"

namespace vtsim {

namespace {

// Pose between a and b at time t, ta < t < tb.
Pose interpolate(const Pose& a, const Pose& b, double t) {
  const double u = (t - a.t_s) / (b.t_s - a.t_s);
  Pose p;
  p.t_s = t;
  p.pos_m = a.pos_m + (b.pos_m - a.pos_m) * u;
  p.q = slerp_shortest(a.q, b.q, u);
  p.vfov_deg = a.vfov_deg + (b.vfov_deg - a.vfov_deg) * u;
  return p;
}

}  // namespace

glm::dquat slerp_shortest(const glm::dquat& a, const glm::dquat& b, double u) {
  if (a == b) return a;
  glm::dquat c = b;
  if (glm::dot(a, b) < 0.0) c = -b;
  // Angle between a and c on the unit 4-sphere (half the rotation angle between them).
  const double theta = 2.0 * std::atan2(glm::length(a - c), glm::length(a + c));
  if (theta < 1e-12) return glm::normalize(a * (1.0 - u) + c * u);
  const double s = std::sin(theta);
  return glm::normalize(a * (std::sin((1.0 - u) * theta) / s) + c * (std::sin(u * theta) / s));
}

Trace resample(const Trace& in, const ResampleOptions& o, ResampleReport* report) {
  if (!(std::isfinite(o.fps) && o.fps > 0.0 && o.fps <= 10000.0))
    throw InputError("fps", fmt::format("{} is not in (0, 10000]", o.fps));
  if (!(std::isfinite(o.gap_s) && o.gap_s > 0.0))
    throw InputError("gap", fmt::format("{} s is not finite and > 0", o.gap_s));
  validate_trace(in, in.name.empty() ? "trace" : in.name);
  const auto& ps = in.poses;

  ResampleReport r;
  for (std::size_t i = 1; i < ps.size(); ++i) {
    const double dt = ps[i].t_s - ps[i - 1].t_s;
    r.longest_gap_s = std::max(r.longest_gap_s, dt);
    if (dt > o.gap_s) {
      if (o.gap_policy == GapPolicy::error)
        throw InputError(fmt::format("{} pose {}", in.name.empty() ? "trace" : in.name, i),
                         fmt::format("gap of {:.6g} s (from t = {:.6f} s to {:.6f} s) is longer "
                                     "than {:g} s",
                                     dt, ps[i - 1].t_s, ps[i].t_s, o.gap_s));
      ++r.gaps;
      r.gap_time_s += dt;
    }
  }

  const double t0 = ps.front().t_s;
  const double span_frames = (ps.back().t_s - t0) * o.fps;
  if (span_frames + 1.0 > static_cast<double>(kMaxTraceFrames))
    throw InputError("fps", fmt::format("{:.0f} frames at {} Hz exceed the limit of {}",
                                        span_frames + 1.0, o.fps, kMaxTraceFrames));
  const auto last_k = static_cast<std::int64_t>(std::floor(span_frames + 1e-6));

  Trace out;
  out.image_width = in.image_width;
  out.image_height = in.image_height;
  out.name = in.name;
  out.source_path = in.source_path;
  out.source_hash = in.source_hash;
  out.poses.reserve(static_cast<std::size_t>(last_k + 1));
  std::size_t j = 0;  // ps[j].t_s <= t < ps[j + 1].t_s
  for (std::int64_t k = 0; k <= last_k; ++k) {
    const double t = t0 + static_cast<double>(k) / o.fps;
    while (j + 1 < ps.size() && ps[j + 1].t_s <= t) ++j;
    Pose p;
    if (j + 1 == ps.size() || ps[j].t_s == t) {
      p = ps[j];  // an exact hit, or past the end (within 1e-6 of a frame): clamp
    } else if (o.gap_policy == GapPolicy::hold && ps[j + 1].t_s - ps[j].t_s > o.gap_s) {
      p = ps[j];
    } else {
      p = interpolate(ps[j], ps[j + 1], t);
    }
    p.t_s = t;
    out.poses.push_back(p);
  }
  r.frames = static_cast<std::int64_t>(out.poses.size());
  if (report) *report = r;
  return out;
}

Trace cut_trace(const Trace& in, double from_s, double to_s) {
  const auto& ps = in.poses;
  if (ps.empty()) throw InputError(in.name, "cut_trace: the trace has no poses");
  const double t0 = ps.front().t_s, t1 = ps.back().t_s;
  if (!std::isfinite(from_s)) throw InputError("--from", "must be a finite time in seconds");
  if (!std::isfinite(to_s)) throw InputError("--to", "must be a finite time in seconds");
  if (!(from_s < to_s)) throw InputError("--from", fmt::format("{} s is not before --to {} s", from_s, to_s));
  if (from_s < t0 || from_s >= t1)
    throw InputError("--from", fmt::format("{} s is outside the trace, which runs from {} s to {} s", from_s, t0, t1));
  if (to_s > t1) throw InputError("--to", fmt::format("{} s is after the trace's end at {} s (it starts at {} s)", to_s, t1, t0));
  Trace out = in;
  out.poses.clear();
  out.poses.push_back(sample_trace(in, from_s));
  out.poses.back().t_s = from_s;
  const auto first = std::upper_bound(ps.begin(), ps.end(), from_s, [](double t, const Pose& p) { return t < p.t_s; });
  for (auto it = first; it != ps.end() && it->t_s < to_s; ++it) out.poses.push_back(*it);
  out.poses.push_back(sample_trace(in, to_s));
  out.poses.back().t_s = to_s;
  return out;
}

Pose sample_trace(const Trace& trace, double t_s) {
  const auto& ps = trace.poses;
  if (ps.empty()) throw InputError(trace.name, "sample_trace: the trace has no poses");
  if (!(t_s > ps.front().t_s)) return ps.front();
  if (!(t_s < ps.back().t_s)) return ps.back();
  const auto it = std::upper_bound(ps.begin(), ps.end(), t_s,
                                   [](double t, const Pose& p) { return t < p.t_s; });
  const Pose& b = *it;
  const Pose& a = *(it - 1);
  if (a.t_s == t_s) return a;
  return interpolate(a, b, t_s);
}

}  // namespace vtsim
