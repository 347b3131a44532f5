#include "core/camera.h"

#include <cmath>
#include <string>

#include <fmt/format.h>
#include <glm/gtc/quaternion.hpp>

#include "core/error.h"

namespace vtsim {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
}  // namespace

double Camera::hfov_deg() const { return 2.0 * std::atan(0.5 * width / focal_px) / kDeg; }
double Camera::vfov_deg() const { return 2.0 * std::atan(0.5 * height / focal_px) / kDeg; }

Camera make_camera(const Pose& pose, int width, int height) {
  return make_camera(pose, width, height, pose.vfov_deg);
}

Camera make_camera(const Pose& pose, int width, int height, double vfov_deg) {
  if (width < 1 || height < 1 || width > kMaxImageSide || height > kMaxImageSide)
    throw InputError("image size", std::to_string(width) + "x" + std::to_string(height) +
                                       " is outside 1.." + std::to_string(kMaxImageSide) + " per side");
  if (!(vfov_deg >= kMinVfov_deg && vfov_deg <= kMaxVfov_deg))
    throw InputError("vfov_deg", fmt::format("vertical field of view {} is not in [{}, {}] degrees", vfov_deg, kMinVfov_deg, kMaxVfov_deg));
  if (!std::isfinite(pose.pos_m.x) || !std::isfinite(pose.pos_m.y) || !std::isfinite(pose.pos_m.z))
    throw InputError("pose.pos_m", "camera position is not finite");
  const glm::dquat& q = pose.q;
  const double n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
  if (!std::isfinite(n2) || n2 < 1e-12)
    throw InputError("pose.q", "orientation quaternion is zero or not finite");
  const glm::dquat u = q * (1.0 / std::sqrt(n2));
  Camera c;
  c.pos_m = pose.pos_m;
  c.fwd = glm::normalize(u * glm::dvec3(1.0, 0.0, 0.0));
  c.left = glm::normalize(u * glm::dvec3(0.0, 1.0, 0.0));
  c.up = glm::normalize(u * glm::dvec3(0.0, 0.0, 1.0));
  c.width = width;
  c.height = height;
  c.focal_px = 0.5 * height / std::tan(0.5 * vfov_deg * kDeg);
  c.cx = 0.5 * width;
  c.cy = 0.5 * height;
  return c;
}

Pose pose_from_angles(const glm::dvec3& pos_m, double yaw_deg, double pitch_deg, double roll_deg,
                      double vfov_deg) {
  // Body rotations applied yaw (about world z), then pitch (about the camera's left axis: a
  // positive angle about +y would tilt forward down, so pitch up is −pitch), then roll about x.
  const glm::dquat yaw = glm::angleAxis(yaw_deg * kDeg, glm::dvec3(0.0, 0.0, 1.0));
  const glm::dquat pitch = glm::angleAxis(-pitch_deg * kDeg, glm::dvec3(0.0, 1.0, 0.0));
  const glm::dquat roll = glm::angleAxis(roll_deg * kDeg, glm::dvec3(1.0, 0.0, 0.0));
  Pose p;
  p.pos_m = pos_m;
  p.q = yaw * pitch * roll;
  p.vfov_deg = vfov_deg;
  return p;
}

Pose trace_pose(const Trace& trace, long long frame) {
  if (frame < 0 || frame >= static_cast<long long>(trace.poses.size()))
    throw InputError("frame", "frame " + std::to_string(frame) + " is outside the trace's " +
                                  std::to_string(trace.poses.size()) + " poses");
  return trace.poses[static_cast<std::size_t>(frame)];
}

Pose trace_pose_at(const Trace& trace, double t_s) {
  if (trace.poses.empty()) throw InputError("time", "the trace has no poses");
  if (!std::isfinite(t_s)) throw InputError("time", "time is not finite");
  const auto& ps = trace.poses;
  if (t_s <= ps.front().t_s) return ps.front();
  if (t_s >= ps.back().t_s) return ps.back();
  std::size_t hi = 1;
  {
    std::size_t lo = 0, n = ps.size() - 1;  // invariant: ps[lo].t_s < t_s <= ps[n].t_s
    while (n - lo > 1) {
      const std::size_t mid = lo + (n - lo) / 2;
      if (ps[mid].t_s < t_s) lo = mid;
      else n = mid;
    }
    hi = n;
  }
  const Pose& a = ps[hi - 1];
  const Pose& b = ps[hi];
  const double span = b.t_s - a.t_s;
  const double w = span > 0.0 ? (t_s - a.t_s) / span : 1.0;
  Pose p;
  p.t_s = t_s;
  p.pos_m = a.pos_m + w * (b.pos_m - a.pos_m);
  p.q = glm::slerp(a.q, b.q, w);
  p.vfov_deg = a.vfov_deg + w * (b.vfov_deg - a.vfov_deg);
  return p;
}

void validate_view_params(const ViewParams& p) {
  if (p.divisor < 1 || p.divisor > 4096) throw InputError("divisor", "must be in [1, 4096]");
  if (!std::isfinite(p.lod_bias) || std::fabs(p.lod_bias) > 64.0f)
    throw InputError("lod_bias", "must be finite and within [-64, 64]");
  if (!(p.max_aniso >= 1.0f && p.max_aniso <= 1024.0f))
    throw InputError("max_aniso", "must be in [1, 1024]");
  if (!(p.near_m > 0.0) || !std::isfinite(p.near_m))
    throw InputError("near_m", "must be finite and > 0");
  if (!(p.far_m > p.near_m)) throw InputError("far_m", "must be greater than near_m");
  for (const int o : {p.sample_ox, p.sample_oy})
    if (o < -1 || o >= p.divisor) throw InputError("sample offset", "must be -1 (the middle) or in [0, divisor)");
}

}  // namespace vtsim
