#pragma once
// Camera traces: timed camera poses. Conventions (docs/architecture.md; formats, importers and
// generators in docs/traces.md and src/sim/trace/trace_*.h):
//  - world: right-handed, z up, metres (x east, y north); double everywhere;
//  - camera body frame "FLU": +x forward (the view direction), +y left, +z up. The identity
//    orientation looks horizontally along world +x with the image's up along world +z.
//  - q rotates camera-frame vectors into the world frame (world = q * body).
#include <cstdint>
#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>
#include <string>
#include <vector>

namespace vtsim {

// Largest image side a trace may declare: 32768 keeps every pixel index of a full-resolution
// image within uint32 (the feedback buffer's pixel field).
inline constexpr int kMaxImageSide = 32768;
// Vertical field of view a pose may carry, degrees: what make_camera accepts, so a trace that
// loads also replays (a tan(vfov/2) near 0 or infinity has no usable focal length).
inline constexpr double kMinVfov_deg = 0.01, kMaxVfov_deg = 179.0;

struct Pose {
  double t_s = 0.0;              // seconds from the trace start
  glm::dvec3 pos_m{0.0};         // camera centre, world metres
  glm::dquat q{1.0, 0.0, 0.0, 0.0};  // unit quaternion, camera (FLU) -> world; glm order w,x,y,z
  double vfov_deg = 60.0;        // vertical field of view, degrees [kMinVfov_deg, kMaxVfov_deg]
};

struct Trace {
  std::vector<Pose> poses;       // strictly increasing t_s
  int image_width = 1920;        // trace-wide image size, pixels
  int image_height = 1080;
  std::string name;              // free text (generator name and parameters, or source file)
  // Where it was read from, the run's trace identity (summary "trace", docs/metrics.md): set by
  // load_any_trace (sim/trace/trace_import.h), kept by resampling; empty / 0 for a generated trace.
  std::string source_path;       // as given to the loader
  std::uint64_t source_hash = 0; // FNV-1a 64 of the file's bytes (core/hash.h)
};

}  // namespace vtsim
