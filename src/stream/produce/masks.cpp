#include "stream/produce/masks.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace vtsim::produce {

double grid_height(const HeightGrid& g, double x_m, double y_m) {
  const double fx = std::clamp((x_m - g.x0_m) / g.spacing_m, 0.0, g.nx - 1.0);
  const double fy = std::clamp((y_m - g.y0_m) / g.spacing_m, 0.0, g.ny - 1.0);
  const int i0 = std::min(static_cast<int>(fx), g.nx - 2), j0 = std::min(static_cast<int>(fy), g.ny - 2);
  const double tx = fx - i0, ty = fy - j0;
  const auto z = [&](int i, int j) { return static_cast<double>(g.z_m[static_cast<std::size_t>(j) * static_cast<std::size_t>(g.nx) + static_cast<std::size_t>(i)]); };
  const double top = z(i0, j0) + (z(i0 + 1, j0) - z(i0, j0)) * tx;
  const double bot = z(i0, j0 + 1) + (z(i0 + 1, j0 + 1) - z(i0, j0 + 1)) * tx;
  return top + (bot - top) * ty;
}

double grid_slope_deg(const HeightGrid& g, double x_m, double y_m) {
  // Central differences one spacing either side, the step shortened where it would leave the grid
  // (so a plane's slope is exact up to the edge).
  const double d = g.spacing_m;
  const double xl = std::max(x_m - d, g.x0_m), xr = std::min(x_m + d, g.x0_m + (g.nx - 1) * d);
  const double yl = std::max(y_m - d, g.y0_m), yr = std::min(y_m + d, g.y0_m + (g.ny - 1) * d);
  const double gx = xr > xl ? (grid_height(g, xr, y_m) - grid_height(g, xl, y_m)) / (xr - xl) : 0.0;
  const double gy = yr > yl ? (grid_height(g, x_m, yr) - grid_height(g, x_m, yl)) / (yr - yl) : 0.0;
  return std::atan(std::hypot(gx, gy)) * (180.0 / 3.14159265358979323846);
}

double soft_range(double v, double lo, double hi, double soft) {
  if (v >= lo && v <= hi) return 1.0;
  if (!(soft > 0)) return 0.0;
  const double out = v < lo ? lo - v : v - hi;
  return std::max(0.0, 1.0 - out / soft);
}

ProceduralMasks procedural_masks(const HeightGrid& g, const std::vector<LayerRule>& rules, int width, int height,
                                 double origin_x_m, double origin_y_m, double m_per_texel) {
  if (g.nx < 2 || g.ny < 2 || !g.z_m) throw InputError("heightfield", fmt::format("{} x {} posts: need at least 2 x 2 with heights", g.nx, g.ny));
  if (!(g.spacing_m > 0)) throw InputError("heightfield", fmt::format("spacing {} m: must be > 0", g.spacing_m));
  if (width < 1 || height < 1 || !(m_per_texel > 0))
    throw InputError("mask", fmt::format("{} x {} texels of {} m: need >= 1 x 1 texels of > 0 m", width, height, m_per_texel));
  if (rules.empty() || rules.size() > static_cast<std::size_t>(kMaxLayers))
    throw InputError("rules", fmt::format("{} rules: give 1 to {}", rules.size(), kMaxLayers));
  for (std::size_t l = 0; l < rules.size(); ++l) {
    const LayerRule& r = rules[l];
    if (!(r.height_soft_m >= 0) || !(r.slope_soft_deg >= 0))
      throw InputError(fmt::format("rules[{}]", l), "soft widths must be >= 0");
    if (!(r.height_lo_m <= r.height_hi_m)) throw InputError(fmt::format("rules[{}].height", l), fmt::format("lo {} > hi {}", r.height_lo_m, r.height_hi_m));
    if (!(r.slope_lo_deg <= r.slope_hi_deg)) throw InputError(fmt::format("rules[{}].slope", l), fmt::format("lo {} > hi {}", r.slope_lo_deg, r.slope_hi_deg));
  }
  ProceduralMasks pm;
  pm.width = width;
  pm.height = height;
  pm.origin_x_m = origin_x_m;
  pm.origin_y_m = origin_y_m;
  pm.m_per_texel = m_per_texel;
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  pm.rgba.assign((rules.size() + 3) / 4, std::vector<std::uint8_t>(n * 4, 0));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double wx = origin_x_m + (x + 0.5) * m_per_texel, wy = origin_y_m + (y + 0.5) * m_per_texel;
      const double h = grid_height(g, wx, wy), s = grid_slope_deg(g, wx, wy);
      const std::size_t t = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
      for (std::size_t l = 0; l < rules.size(); ++l) {
        const LayerRule& r = rules[l];
        const double f = soft_range(h, r.height_lo_m, r.height_hi_m, r.height_soft_m) * soft_range(s, r.slope_lo_deg, r.slope_hi_deg, r.slope_soft_deg);
        pm.rgba[l / 4][t * 4 + l % 4] = static_cast<std::uint8_t>(std::lround(255.0 * f));
      }
    }
  return pm;
}

}  // namespace vtsim::produce
