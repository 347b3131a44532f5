#pragma once
// Level of detail from screen-space texture-coordinate derivatives (seed 000 §2-2-3: Heckbert's
// rule, LOD = log2 of the larger of the two footprint lengths) and the ray-differential footprint
// of a ray hitting a plane. Header-only: these run once per feedback sample and must inline.
#include <bit>
#include <cstdint>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace vtsim {

// log2(x) for finite x > 0, including subnormals not needed: callers clamp to [2^-128, 2^128].
// Exponent from the bits, mantissa reduced to [sqrt(1/2), sqrt(2)) and log2 m = (2/ln 2)·atanh(y),
// y = (m-1)/(m+1), |y| <= 0.1716, summed to y^9: truncation error < 1.1e-9, so |error| < 2e-9
// over the whole range; exactly 0 at m = 1, so exact at every power of two.
inline double fast_log2(double x) {
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(x);
  int e = static_cast<int>((bits >> 52) & 0x7ff) - 1023;
  double m = std::bit_cast<double>((bits & 0x000fffffffffffffULL) | 0x3ff0000000000000ULL);
  if (m > 1.4142135623730951) {  // sqrt(2): centre the interval on 1 to shrink |y|
    m *= 0.5;
    ++e;
  }
  const double y = (m - 1.0) / (m + 1.0);
  const double y2 = y * y;
  // 2/(k ln 2) for k = 1, 3, 5, 7, 9.
  constexpr double c1 = 2.8853900817779268, c3 = 0.96179669392597561, c5 = 0.57707801635558537,
                   c7 = 0.41219858311113240, c9 = 0.32059889797532520;
  return static_cast<double>(e) + y * (c1 + y2 * (c3 + y2 * (c5 + y2 * (c7 + y2 * c9))));
}

// The LOD rule of ViewParams, prepared once per frame.
struct LodRule {
  double bias = 0.0;            // added to every LOD
  bool anisotropic = false;     // false: Heckbert max of lengths
  double inv_aniso2 = 1.0 / 256.0;  // 1 / max_aniso^2
};

// Footprints are clamped to [2^-64, 2^64] level-0 texels per full-resolution pixel (LOD in
// [-64, 64] before bias): keeps the LOD finite for degenerate footprints (a zero-length derivative
// of a surface seen exactly edge-on or at the camera centre, an infinite one at the horizon)
// while covering any texture TileKey can address (2^34 texels) with a wide margin.
inline constexpr double kMinFootprint2 = 0x1p-128, kMaxFootprint2 = 0x1p128;

// LOD from the squared lengths of dT/dx and dT/dy (level-0 texels per full-resolution pixel).
// Isotropic (Heckbert): log2 max(|dT/dx|, |dT/dy|). Anisotropic (as GPUs do it):
// log2(major / min(major/minor, max_aniso)) = log2 max(minor, major / max_aniso).
// Computed on squares (0.5·log2) to avoid two square roots. NaN maps to the lower clamp.
inline double lod_from_lengths2(double lx2, double ly2, const LodRule& r) {
  double q;
  if (!r.anisotropic) {
    q = lx2 > ly2 ? lx2 : ly2;
  } else {
    const double major = lx2 > ly2 ? lx2 : ly2, minor = lx2 > ly2 ? ly2 : lx2;
    const double m = major * r.inv_aniso2;
    q = minor > m ? minor : m;
  }
  if (!(q >= kMinFootprint2)) q = kMinFootprint2;
  if (q > kMaxFootprint2) q = kMaxFootprint2;
  return 0.5 * fast_log2(q) + r.bias;
}

// Ray differentials on a plane (Igehy 1999): a ray o + t·d with d linear in the pixel position
// hits a plane of normal n at t; moving the pixel by one full-resolution pixel changes d by ddx
// (ddy), and the hit point by dP = t·(ddx − (ddx·n)/(d·n)·d). Texel coordinates are affine on the
// plane with gradients gu, gv (texels per metre, world vectors), so dT/dx = (gu·dPx, gv·dPx).
// Requires d·n != 0 (callers only shade surfaces seen from the front, d·n < 0).
inline double plane_footprint_lod(const glm::dvec3& d, double t, const glm::dvec3& n,
                                  const glm::dvec3& ddx, const glm::dvec3& ddy,
                                  const glm::dvec3& gu, const glm::dvec3& gv, const LodRule& r) {
  const double inv_dn = 1.0 / glm::dot(d, n);
  const glm::dvec3 dpx = t * (ddx - (glm::dot(ddx, n) * inv_dn) * d);
  const glm::dvec3 dpy = t * (ddy - (glm::dot(ddy, n) * inv_dn) * d);
  const double ux = glm::dot(gu, dpx), vx = glm::dot(gv, dpx);
  const double uy = glm::dot(gu, dpy), vy = glm::dot(gv, dpy);
  return lod_from_lengths2(ux * ux + vx * vx, uy * uy + vy * vy, r);
}

}  // namespace vtsim
