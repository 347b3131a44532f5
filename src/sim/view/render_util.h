#pragma once
// Shared plumbing of the scene renderers (internal to src/sim).
#include <cmath>
#include <cstddef>

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

// Level-0 texel of a continuous texel coordinate, or false when outside [0, extent) or NaN.
inline bool texel_index(double t, std::int64_t extent, std::int64_t& out) {
  if (!(t >= 0.0 && t < static_cast<double>(extent))) return false;
  out = static_cast<std::int64_t>(t);  // t >= 0: truncation is floor
  if (out >= extent) out = extent - 1;  // t within an ulp below extent rounds up when > 2^53
  return true;
}

}  // namespace vtsim::detail
