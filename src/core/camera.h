#pragma once
// Pinhole camera of the feedback renderer: a Pose (FLU camera frame, docs/architecture.md) plus
// the full-resolution image size and vertical field of view; square pixels, principal point at
// the image centre. Pixel coordinates (px, py): px grows right, py down; the centre of
// full-resolution pixel i is at i + 0.5.
#include <glm/vec3.hpp>

#include "core/trace.h"
#include "core/view.h"

namespace vtsim {

struct Camera {
  glm::dvec3 pos_m{0.0};          // camera centre, world metres
  glm::dvec3 fwd{1.0, 0.0, 0.0};  // unit view direction (camera +x), world
  glm::dvec3 left{0.0, 1.0, 0.0}; // unit camera +y, world
  glm::dvec3 up{0.0, 0.0, 1.0};   // unit camera +z, world
  int width = 1920, height = 1080;  // full-resolution image, pixels
  double focal_px = 935.3074360871938;  // pixels per unit tangent: (height/2) / tan(vfov/2)
  double cx = 960.0, cy = 540.0;  // principal point (image centre), pixels

  // Unnormalised direction of the ray through pixel position (px, py):
  // focal·fwd + (cx − px)·left + (cy − py)·up. Its component along fwd is focal_px, so a hit at
  // ray parameter t has view depth t·focal_px. Moving one pixel right adds −left, down adds −up.
  glm::dvec3 ray_dir(double px, double py) const {
    return focal_px * fwd + (cx - px) * left + (cy - py) * up;
  }
  double hfov_deg() const;
  double vfov_deg() const;
};

// Throws InputError (where = "pose.q", "pose.pos_m", "vfov_deg", "image size") for a non-finite
// position, a zero or non-finite quaternion (it is normalised otherwise), a field of view outside
// [0.01, 179] degrees or an image side outside [1, kMaxImageSide].
Camera make_camera(const Pose& pose, int width, int height);           // vfov from the pose
Camera make_camera(const Pose& pose, int width, int height, double vfov_deg);

// A pose from position and heading: yaw counter-clockwise from world +x about +z, pitch up from
// the horizon, roll about the view axis (right side down for positive roll), all degrees.
Pose pose_from_angles(const glm::dvec3& pos_m, double yaw_deg, double pitch_deg, double roll_deg = 0.0,
                      double vfov_deg = 60.0);

// Pose of frame `frame` of a trace; throws InputError("frame", ...) when out of range.
Pose trace_pose(const Trace& trace, long long frame);
// Pose at time t_s: position interpolated linearly and orientation by slerp between the poses
// around t_s, field of view linearly; clamped to the first/last pose outside the trace.
// Throws InputError("time", ...) for an empty trace or non-finite t_s.
Pose trace_pose_at(const Trace& trace, double t_s);

// Feedback-buffer geometry (docs/view.md): the buffer is ceil(W/divisor) × ceil(H/divisor); buffer
// pixel b stands for the full-resolution block [b·divisor, min(full, (b+1)·divisor)) and samples at
// the centre of the block's middle pixel, floor((start + end) / 2) + 0.5, so every buffer sample
// is exactly a full-resolution pixel centre (divisor 8 samples a subset of divisor 1's samples).
inline int buffer_extent(int full, int divisor) { return (full + divisor - 1) / divisor; }
inline int sample_pixel(int b, int divisor, int full) {
  const int start = b * divisor;
  const int end = start + divisor < full ? start + divisor : full;
  return (start + end) / 2;
}
inline double sample_pos(int b, int divisor, int full) { return sample_pixel(b, divisor, full) + 0.5; }

// Throws InputError naming the field for divisor outside [1, 4096], non-finite lod_bias or
// |lod_bias| > 64, max_aniso not in [1, 1024], near_m not finite and > 0, far_m <= near_m or NaN.
void validate_view_params(const ViewParams& p);

}  // namespace vtsim
