#pragma once
// Shared plumbing of the scene renderers (internal to src/sim).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>

#include "core/camera.h"
#include "sim/view/lod.h"
#include "core/view.h"

namespace vtsim::detail {

// Validates the parameters, sizes the buffer and clears its samples and counters, keeping the
// sample storage (reserve is a no-op after the first frame of a given size).
inline void begin_frame(const Camera& cam, const ViewParams& p, ViewBuffer& out) {
  validate_view_params(p);
  out.width = buffer_extent(cam.width, p.divisor);
  out.height = buffer_extent(cam.height, p.divisor);
  out.divisor = p.divisor;
  out.counters = ViewCounters{};
  out.samples.clear();
  out.samples.reserve(static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.height));
}

inline LodRule lod_rule(const ViewParams& p) {
  LodRule r;
  r.bias = static_cast<double>(p.lod_bias);
  r.anisotropic = p.anisotropic;
  const double a = static_cast<double>(p.max_aniso);
  r.inv_aniso2 = 1.0 / (a * a);
  return r;
}

// Narrows [t0, t1] to the part of the ray o + t·d inside box [lo, hi] (slabs, Kay & Kajiya 1986);
// false when nothing is left. d need not be unit; a zero component tests o against that slab.
inline bool clip_ray_to_box(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi,
                            double& t0, double& t1) {
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0) {
      if (o[k] < lo[k] || o[k] > hi[k]) return false;
      continue;
    }
    double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 <= t1;
}

// Level-0 texel of a continuous texel coordinate, or false when outside [0, extent) or NaN.
inline bool texel_index(double t, std::int64_t extent, std::int64_t& out) {
  if (!(t >= 0.0 && t < static_cast<double>(extent))) return false;
  out = static_cast<std::int64_t>(t);  // t >= 0: truncation is floor
  if (out >= extent) out = extent - 1;  // t within an ulp below extent rounds up when > 2^53
  return true;
}

}  // namespace vtsim::detail
