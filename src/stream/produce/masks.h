#pragma once
// Procedural weight masks from a heightfield (VT Terrain Design: "if the mask can be computed from the
// terrain mesh's procedural parameters, no mask texture is needed"): per layer a rule of height
// and slope ranges with soft edges, evaluated at each mask texel's centre, written as the RGBA8
// WeightMask channels the compositor reads (layer l in channel l % 4 of mask l / 4).
// docs/produced.md, "Procedural masks".
//
// Height at a point: the bilinear interpolant of the posts (clamped at the grid's edge). Slope:
// atan(|grad z|) in degrees, grad z by central differences of that interpolant one post spacing
// either side (so a plane z = a x + b y gives exactly atan(hypot(a, b)) inside the grid). A rule's
// factor for a value v and range [lo, hi] with soft width t: 1 inside, falling linearly to 0 at
// lo - t and hi + t (t = 0: a hard edge, v exactly on it inside). weight = round(255 f_height
// f_slope). Weights need not sum to 255: the compositor normalises them per texel.
//
// The grid is a view of the caller's heights (sim/view/scene_heightfield.h's Heightfield has the
// same fields; this floor cannot include it). Complexity O(mask texels x layers); pure functions,
// thread-safe.
#include <cstdint>
#include <limits>
#include <vector>

#include "stream/produce/compositor.h"

namespace vtsim::produce {

struct HeightGrid {
  int nx = 0, ny = 0;             // posts along x and y (>= 2 each)
  double spacing_m = 1;           // distance between neighbouring posts, m
  double x0_m = 0, y0_m = 0;      // world position of post (0, 0), m
  const float* z_m = nullptr;     // nx * ny heights, m, row-major: z_m[j nx + i]
};

struct LayerRule {
  double height_lo_m = -std::numeric_limits<double>::infinity();  // full weight from here, m
  double height_hi_m = std::numeric_limits<double>::infinity();   // ... up to here, m
  double height_soft_m = 0;     // linear fade outside [lo, hi] to 0 over this width, m
  double slope_lo_deg = 0;      // full weight from this slope, degrees
  double slope_hi_deg = 90;     // ... up to this slope, degrees
  double slope_soft_deg = 0;    // linear fade outside [lo, hi] over this width, degrees
};

// Bilinear height at (x, y), clamped to the grid; and the slope there in degrees.
double grid_height(const HeightGrid& g, double x_m, double y_m);
double grid_slope_deg(const HeightGrid& g, double x_m, double y_m);
// The factor of one range (see the file comment).
double soft_range(double v, double lo, double hi, double soft);

// ceil(rules / 4) masks of width x height texels of m_per_texel whose texel (0, 0)'s corner is at
// (origin_x_m, origin_y_m); channels of layers past rules.size() are 0. Throws InputError naming
// the field for a grid of fewer than 2 x 2 posts or without heights, a bad size, more than
// kMaxLayers rules, a negative soft width or lo > hi.
struct ProceduralMasks {
  int width = 0, height = 0;
  double origin_x_m = 0, origin_y_m = 0, m_per_texel = 1;
  std::vector<std::vector<std::uint8_t>> rgba;  // one width * height * 4 image per mask
  // The compositor's view of mask i (valid while this object lives and is not moved from).
  WeightMask mask(std::size_t i) const { return {width, height, rgba[i].data(), origin_x_m, origin_y_m, m_per_texel}; }
};
ProceduralMasks procedural_masks(const HeightGrid& grid, const std::vector<LayerRule>& rules, int width, int height,
                                 double origin_x_m, double origin_y_m, double m_per_texel);

}  // namespace vtsim::produce
