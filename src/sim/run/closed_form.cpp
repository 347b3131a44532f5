#include "sim/run/closed_form.h"

#include <cmath>

namespace vtsim {

double clipmap_walk_disk_Bps(const ClosedFormWalk& w) {
  double levels = 0.0;  // Σ_{l<S} 2^-l
  for (int l = 0; l < w.stack_levels; ++l) levels += std::ldexp(1.0, -l);
  const double N = w.clipsize, T = w.tile_size, v = w.speed_mps, tpm = w.texels_per_m, B = w.bytes_per_texel;
  const double h = w.heading_deg * 3.14159265358979323846 / 180.0;
  const double cx = std::fabs(std::cos(h)), cy = std::fabs(std::sin(h));
  if (std::fabs(cx - cy) < 1e-12)  // exact diagonal: shared corner tile every step
    return v * cx * tpm * (2.0 * N - T) * B * levels;
  return v * (cx + cy) * tpm * N * B * levels;
}

}  // namespace vtsim
