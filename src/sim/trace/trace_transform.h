#pragma once
// Bringing a recorded trajectory into vtsim's conventions and onto a terrain (docs/traces.md,
// "Transforms"): axis conventions of the source world and camera, then recentre, yaw, scale and
// offset for positions, and rebase, scale and offset for time.
#include <glm/mat3x3.hpp>
#include <string>
#include <string_view>

#include "core/trace.h"

namespace vtsim {

// A right-handed axis convention: the rotation taking source-axis coordinates to vtsim's axes
// (world: x east, y north, z up; camera: FLU). Columns are the images of the source x, y, z axes.
struct AxisConvention {
  std::string spec;  // canonical three letters, e.g. "ENU", "RDF"
  glm::dmat3 to_vtsim{1.0};
};

// Source world axes. Names: "z-up" (= ENU, vtsim's own), "y-up" (EUS: x east, y up, z south, the
// right-handed graphics convention), "y-down" or "-y-up" (EDN: x east, y down, z north, the
// first-camera frame of KITTI), "ned" (NED, aerospace). Or three letters from E/W/N/S/U/D naming
// where the source x, y, z axes point. Throws InputError(where, ...) for an unknown or left-handed spec.
AxisConvention parse_world_axes(std::string_view spec, const std::string& where);

// Source camera axes. Names: "optical" (RDF: x right, y down, z forward; TUM, KITTI, OpenCV),
// "flu" (vtsim's own), "opengl" (RUB: x right, y up, z backward), "imu-urf" (URF: x up, y right,
// z forward; the EuRoC MAV body frame). Or three letters from F/B/L/R/U/D.
AxisConvention parse_camera_axes(std::string_view spec, const std::string& where);

// What transform_trace does, in this order (each step on every pose):
//   1. time:  t' = (rebase_time ? t - t_first : t) * time_scale + time_offset_s
//   2. axes:  p1 = W * (recenter ? p - p_first : p);      q1 = qW * q * conj(qC)
//             (W, qW from world_axes; qC from camera_axes: q then maps FLU vectors to the world)
//   3. yaw:   p2 = Rz(yaw) * p1;                          q2 = qz(yaw) * q1
//   4. scale and offset: p' = offset_m + scale * p2        (orientation unchanged)
// Empty axis strings mean vtsim's own conventions (ENU world, FLU camera).
struct TraceTransform {
  double scale = 1.0;             // > 0; multiplies positions (a room metre becomes `scale` metres)
  glm::dvec3 offset_m{0.0};       // added last, world metres
  bool recenter = false;          // subtract the first position before anything else
  double yaw_deg = 0.0;           // rotation about world +z, counter-clockwise seen from above
  std::string world_axes;         // source world convention (see parse_world_axes); "" = ENU
  std::string camera_axes;        // source camera convention (see parse_camera_axes); "" = FLU
  double time_scale = 1.0;        // > 0; 2 plays the recording at half speed
  double time_offset_s = 0.0;     // added last, seconds
  bool rebase_time = true;        // subtract the first time (the trace starts at time_offset_s)
  double vfov_deg = 0.0;          // > 0: replace every pose's vfov; 0: keep
};

// Applies tf in place and validates the result (validate_trace). Throws InputError(where, ...)
// for bad parameters or a result out of range.
void transform_trace(Trace& trace, const TraceTransform& tf, const std::string& where = "transform");

// The inverse of transform_trace's axes step (2) alone, for writers: poses in vtsim's conventions
// expressed in the source conventions world_axes / camera_axes (empty: ENU / FLU), so that
// importing them with those conventions gives them back: p = W^T p' (exact: W is a signed
// permutation), q = normalize(conj(qW) q' qC) (to rounding, ~1e-16). What is the identity is
// skipped, so ENU / FLU leaves the trace bit for bit. Throws InputError(where + ": world_axes" or
// ": camera_axes", ...) for a bad spec.
void to_source_axes(Trace& trace, std::string_view world_axes, std::string_view camera_axes,
                    const std::string& where);

// Orientation quaternion for a camera with heading (yaw, counter-clockwise from +x) and pitch
// (up positive), no roll: qz(yaw) * qy(-pitch). Degrees.
glm::dquat yaw_pitch_quat(double yaw_deg, double pitch_deg);

}  // namespace vtsim
