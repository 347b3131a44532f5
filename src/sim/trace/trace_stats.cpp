#include "sim/trace/trace_stats.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>

#include "core/error.h"
#include "sim/trace/trace_io.h"

namespace vtsim {

namespace {

// Nearest-rank percentile of sorted values: the smallest value with at least p% at or below it.
double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  auto rank = static_cast<std::size_t>(std::ceil(p / 100.0 * static_cast<double>(sorted.size())));
  rank = std::clamp<std::size_t>(rank, 1, sorted.size());
  return sorted[rank - 1];
}

nlohmann::json events_json(const std::vector<TraceEvent>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (const TraceEvent& e : v)
    a.push_back({{"pose", e.pose}, {"t_s", e.t_s}, {"distance_m", e.distance_m}, {"dt_s", e.dt_s}});
  return a;
}

}  // namespace

double rotation_angle(const glm::dquat& a, const glm::dquat& b) {
  // r = conj(a) * b; angle = 2 atan2(|r.xyz|, |r.w|) (robust for tiny angles, unlike acos).
  const glm::dquat r = glm::conjugate(a) * b;
  const double s = std::sqrt(r.x * r.x + r.y * r.y + r.z * r.z);
  return 2.0 * std::atan2(s, std::abs(r.w));
}

TraceStats trace_stats(const Trace& trace, const TraceStatsOptions& o) {
  validate_trace(trace, trace.name.empty() ? "trace" : trace.name);
  if (!(o.cut_speed_mps > 0.0) || !(o.cut_distance_m >= 0.0) || !(o.gap_s > 0.0) ||
      !(o.min_step_s >= 0.0) || !std::isfinite(o.min_step_s))
    throw InputError("trace_stats", "cut speed and gap must be > 0, cut distance and min step >= 0");
  const auto& ps = trace.poses;
  TraceStats s;
  s.frames = static_cast<std::int64_t>(ps.size());
  s.duration_s = ps.back().t_s - ps.front().t_s;
  s.mean_rate_hz = ps.size() > 1 ? static_cast<double>(ps.size() - 1) / s.duration_s : 0.0;
  s.image_width = trace.image_width;
  s.image_height = trace.image_height;
  s.bbox_min_m = s.bbox_max_m = ps.front().pos_m;
  s.vfov_min_deg = s.vfov_max_deg = ps.front().vfov_deg;
  std::vector<double> speeds;
  speeds.reserve(ps.size());
  double max_ang = 0.0;
  std::size_t anchor = 0;  // start of the current speed step
  const auto close_step = [&](std::size_t end) {
    const double dt = ps[end].t_s - ps[anchor].t_s;
    const glm::dvec3 d = ps[end].pos_m - ps[anchor].pos_m;
    speeds.push_back(std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z) / dt);
    max_ang = std::max(max_ang, rotation_angle(ps[anchor].q, ps[end].q) / dt);
    anchor = end;
  };
  for (std::size_t i = 1; i < ps.size(); ++i) {
    const Pose& a = ps[i - 1];
    const Pose& b = ps[i];
    s.bbox_min_m = glm::min(s.bbox_min_m, b.pos_m);
    s.bbox_max_m = glm::max(s.bbox_max_m, b.pos_m);
    s.vfov_min_deg = std::min(s.vfov_min_deg, b.vfov_deg);
    s.vfov_max_deg = std::max(s.vfov_max_deg, b.vfov_deg);
    const double dt = b.t_s - a.t_s;
    s.dt_min_s = i == 1 ? dt : std::min(s.dt_min_s, dt);
    s.dt_max_s = std::max(s.dt_max_s, dt);
    const glm::dvec3 d = b.pos_m - a.pos_m;
    const double dist = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    const TraceEvent ev{static_cast<std::int64_t>(i), b.t_s, dist, dt};
    if (dt > o.gap_s) {
      ++s.gaps;
      if (s.gap_list.size() < o.max_listed) s.gap_list.push_back(ev);
    }
    if (dist / dt > o.cut_speed_mps && dist > o.cut_distance_m) {
      ++s.cuts;
      s.cut_distance_max_m = std::max(s.cut_distance_max_m, dist);
      if (s.cut_list.size() < o.max_listed) s.cut_list.push_back(ev);
      anchor = i;  // a step never spans a cut; a short run before it is dropped
      continue;
    }
    s.path_length_m += dist;
    if (b.t_s - ps[anchor].t_s >= o.min_step_s) close_step(i);
  }
  if (speeds.empty() && anchor + 1 < ps.size()) close_step(ps.size() - 1);
  s.speed_steps = static_cast<std::int64_t>(speeds.size());
  std::sort(speeds.begin(), speeds.end());
  s.speed_p50_mps = percentile(speeds, 50.0);
  s.speed_p99_mps = percentile(speeds, 99.0);
  s.speed_max_mps = speeds.empty() ? 0.0 : speeds.back();
  s.angular_speed_max_dps = max_ang * (180.0 / std::numbers::pi);
  return s;
}

nlohmann::json to_json(const TraceStats& s) {
  const auto vec = [](const glm::dvec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); };
  return {
      {"frames", s.frames},
      {"duration_s", s.duration_s},
      {"mean_rate_hz", s.mean_rate_hz},
      {"dt_min_s", s.dt_min_s},
      {"dt_max_s", s.dt_max_s},
      {"path_length_m", s.path_length_m},
      {"speed_p50_mps", s.speed_p50_mps},
      {"speed_p99_mps", s.speed_p99_mps},
      {"speed_max_mps", s.speed_max_mps},
      {"angular_speed_max_dps", s.angular_speed_max_dps},
      {"speed_steps", s.speed_steps},
      {"bbox_min_m", vec(s.bbox_min_m)},
      {"bbox_max_m", vec(s.bbox_max_m)},
      {"vfov_min_deg", s.vfov_min_deg},
      {"vfov_max_deg", s.vfov_max_deg},
      {"cuts", s.cuts},
      {"cut_distance_max_m", s.cut_distance_max_m},
      {"cut_list", events_json(s.cut_list)},
      {"gaps", s.gaps},
      {"gap_list", events_json(s.gap_list)},
      {"image_width", s.image_width},
      {"image_height", s.image_height},
  };
}

}  // namespace vtsim
