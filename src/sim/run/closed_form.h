#pragma once
// Closed-form figures the simulator is checked against (docs/clipmap.md derives them).
#include <cstdint>

namespace vtsim {

// A camera moving in a straight line at constant speed over a clipmap whose every stack level is
// updated (the view wants level 0), devices unconstrained.
struct ClosedFormWalk {
  double speed_mps = 1.5;
  double heading_deg = 0.0;     // 0 (axis-aligned) or 45 (exact diagonal) are the exact cases
  double texels_per_m = 128.0;  // level 0
  int clipsize = 1024;          // N, texels
  int tile_size = 128;          // T, texels
  double bytes_per_texel = 4.0; // summed over layers
  int stack_levels = 6;         // S: levels larger than N
};

// Steady-state disk bytes/s. Level l's ground texel moves at v·tpm/2^l texels/s per unit of
// direction cosine; its window steps one tile each T texels, loading a column of N/T tiles
// (N·T texels). Axis-aligned: v·tpm·N·B·Σ_{l<S} 2^-l. Exact 45°: both axes step in the same frame
// and the corner tile is shared, (2N − T)·T texels per step at (v/√2)·tpm/(2^l·T) steps/s:
// (v/√2)·tpm·(2N − T)·B·Σ 2^-l. Other headings: |cos|+|sin| weighting without the shared corner
// (an upper bound within (T/2N) of the truth).
double clipmap_walk_disk_Bps(const ClosedFormWalk& w);

}  // namespace vtsim
