#include "sim/trace/trace_transform.h"

#include <fmt/core.h>

#include <glm/gtc/quaternion.hpp>
#include <glm/matrix.hpp>

#include <cctype>
#include <cmath>
#include <numbers>

#include "core/error.h"
#include "sim/trace/trace_io.h"

namespace vtsim {

namespace {

struct Letter {
  char c;
  glm::dvec3 dir;
};

constexpr Letter kWorldLetters[] = {{'E', {1, 0, 0}}, {'W', {-1, 0, 0}}, {'N', {0, 1, 0}},
                                    {'S', {0, -1, 0}}, {'U', {0, 0, 1}},  {'D', {0, 0, -1}}};
constexpr Letter kCameraLetters[] = {{'F', {1, 0, 0}}, {'B', {-1, 0, 0}}, {'L', {0, 1, 0}},
                                     {'R', {0, -1, 0}}, {'U', {0, 0, 1}},  {'D', {0, 0, -1}}};

template <std::size_t N>
[[noreturn]] void fail_axes(std::string_view spec, const Letter (&letters)[N], std::string_view kind,
                            std::string_view why, const std::string& where) {
  std::string alphabet;
  for (const Letter& l : letters) alphabet += l.c;
  throw InputError(where, fmt::format("{} axes '{}': {} (use a name, or three letters from {} "
                                      "giving where the source x, y, z axes point)",
                                      kind, spec, why, alphabet));
}

template <std::size_t N>
AxisConvention parse_letters(std::string_view spec, const Letter (&letters)[N], std::string_view kind,
                             const std::string& where) {
  const auto fail = [&](std::string_view why) { fail_axes(spec, letters, kind, why, where); };
  if (spec.size() != 3) fail("unknown convention");
  AxisConvention a;
  bool used[3] = {false, false, false};
  for (int col = 0; col < 3; ++col) {
    const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(spec[static_cast<std::size_t>(col)])));
    const Letter* hit = nullptr;
    for (const Letter& l : letters)
      if (l.c == c) hit = &l;
    if (!hit) fail_axes(spec, letters, kind, "unknown convention", where);
    int axis = 0;
    while (hit->dir[axis] == 0.0) ++axis;
    if (used[axis]) fail("two source axes point along the same line");
    used[axis] = true;
    a.to_vtsim[col] = hit->dir;
    a.spec += c;
  }
  if (glm::determinant(a.to_vtsim) < 0.0) fail("left-handed (a mirror image cannot be a rotation)");
  return a;
}

bool is_identity(const glm::dquat& q) { return q.w == 1.0 && q.x == 0.0 && q.y == 0.0 && q.z == 0.0; }

glm::dquat to_quat(const AxisConvention& a) { return glm::normalize(glm::quat_cast(a.to_vtsim)); }

double deg_to_rad(double d) { return d * (std::numbers::pi / 180.0); }

}  // namespace

AxisConvention parse_world_axes(std::string_view spec, const std::string& where) {
  std::string_view letters = spec;
  if (spec == "z-up" || spec == "enu") letters = "ENU";
  else if (spec == "y-up") letters = "EUS";
  else if (spec == "y-down" || spec == "-y-up") letters = "EDN";
  else if (spec == "ned") letters = "NED";
  return parse_letters(letters, kWorldLetters, "world", where);
}

AxisConvention parse_camera_axes(std::string_view spec, const std::string& where) {
  std::string_view letters = spec;
  if (spec == "optical") letters = "RDF";
  else if (spec == "flu") letters = "FLU";
  else if (spec == "opengl") letters = "RUB";
  else if (spec == "imu-urf") letters = "URF";
  return parse_letters(letters, kCameraLetters, "camera", where);
}

glm::dquat yaw_pitch_quat(double yaw_deg, double pitch_deg) {
  const double yaw = deg_to_rad(yaw_deg), pitch = deg_to_rad(pitch_deg);
  // Rotation about +y by -pitch tilts FLU forward (+x) up for a positive pitch.
  const glm::dquat qy(std::cos(-pitch / 2), 0.0, std::sin(-pitch / 2), 0.0);
  const glm::dquat qz(std::cos(yaw / 2), 0.0, 0.0, std::sin(yaw / 2));
  return qz * qy;
}

void transform_trace(Trace& trace, const TraceTransform& tf, const std::string& where) {
  const auto need = [&](bool ok, std::string_view field, double v, std::string_view rule) {
    if (!ok) throw InputError(fmt::format("{}: {}", where, field), fmt::format("{} {}", v, rule));
  };
  need(std::isfinite(tf.scale) && tf.scale > 0.0, "scale", tf.scale, "must be finite and > 0");
  for (int k = 0; k < 3; ++k) need(std::isfinite(tf.offset_m[k]), "offset", tf.offset_m[k], "must be finite");
  need(std::isfinite(tf.yaw_deg), "yaw", tf.yaw_deg, "must be finite");
  need(std::isfinite(tf.time_scale) && tf.time_scale > 0.0, "time_scale", tf.time_scale,
       "must be finite and > 0");
  need(std::isfinite(tf.time_offset_s), "time_offset", tf.time_offset_s, "must be finite");
  need(tf.vfov_deg == 0.0 || (tf.vfov_deg >= kMinVfov_deg && tf.vfov_deg <= kMaxVfov_deg), "vfov", tf.vfov_deg,
       "must be in [0.01, 179], or 0 to keep");
  const AxisConvention world =
      parse_world_axes(tf.world_axes.empty() ? "ENU" : tf.world_axes, where + ": world_axes");
  const AxisConvention camera =
      parse_camera_axes(tf.camera_axes.empty() ? "FLU" : tf.camera_axes, where + ": camera_axes");
  if (trace.poses.empty()) throw InputError(where, "the trace has no poses");

  const double t0 = tf.rebase_time ? trace.poses.front().t_s : 0.0;
  const glm::dvec3 p0 = tf.recenter ? trace.poses.front().pos_m : glm::dvec3(0.0);
  const double yaw = deg_to_rad(tf.yaw_deg);
  const double cy = std::cos(yaw), sy = std::sin(yaw);
  const glm::dquat q_pre = yaw_pitch_quat(tf.yaw_deg, 0.0) * to_quat(world);
  const glm::dquat q_post = glm::conjugate(to_quat(camera));
  const bool rotate_q = !is_identity(q_pre) || !is_identity(q_post);
  for (Pose& p : trace.poses) {
    p.t_s = (p.t_s - t0) * tf.time_scale + tf.time_offset_s;
    glm::dvec3 v = world.to_vtsim * (p.pos_m - p0);
    if (tf.yaw_deg != 0.0) v = glm::dvec3(cy * v.x - sy * v.y, sy * v.x + cy * v.y, v.z);
    p.pos_m = tf.offset_m + tf.scale * v;
    if (rotate_q) p.q = glm::normalize(q_pre * p.q * q_post);
    if (tf.vfov_deg > 0.0) p.vfov_deg = tf.vfov_deg;
  }
  validate_trace(trace, where);
}

void to_source_axes(Trace& trace, std::string_view world_axes, std::string_view camera_axes,
                    const std::string& where) {
  const AxisConvention world = parse_world_axes(world_axes.empty() ? "ENU" : world_axes, where + ": world_axes");
  const AxisConvention camera =
      parse_camera_axes(camera_axes.empty() ? "FLU" : camera_axes, where + ": camera_axes");
  const bool move_p = world.to_vtsim != glm::dmat3(1.0);
  const glm::dmat3 to_source = glm::transpose(world.to_vtsim);
  const glm::dquat q_pre = glm::conjugate(to_quat(world));
  const glm::dquat q_post = to_quat(camera);
  const bool rotate_q = !is_identity(q_pre) || !is_identity(q_post);
  for (Pose& p : trace.poses) {
    if (move_p) p.pos_m = to_source * p.pos_m;
    if (rotate_q) p.q = glm::normalize(q_pre * p.q * q_post);
  }
}

}  // namespace vtsim
