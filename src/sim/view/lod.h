#pragma once
// Level of detail from screen-space texture-coordinate derivatives (Yao 2007 §2-2-3: Heckbert's
// rule, LOD = log2 of the larger of the two footprint lengths) and the ray-differential footprint
// of a ray hitting a plane. Header-only: these run once per feedback sample and must inline.
#include <bit>
#include <cstdint>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace vtsim {

namespace detail {

// ln(x) for x in [1, 2] at compile time: 2·atanh(y), y = (x−1)/(x+1) <= 1/3, 40 terms of the
// series (the first omitted term is below 1e-40).
constexpr double ln_1_2(double x) {
  const double y = (x - 1.0) / (x + 1.0), y2 = y * y;
  double term = y, sum = 0.0;
  for (int k = 0; k < 40; ++k) {
    sum += term / (2 * k + 1);
    term *= y2;
  }
  return 2.0 * sum;
}

inline constexpr int kLog2TableBits = 8;
struct Log2Table {
  double log2_mi[1 << kLog2TableBits];  // log2(1 + i/256)
  double inv_mi[1 << kLog2TableBits];   // 1 / (1 + i/256)
};
constexpr Log2Table make_log2_table() {
  Log2Table t{};
  constexpr double kInvLn2 = 1.4426950408889634;
  for (int i = 0; i < (1 << kLog2TableBits); ++i) {
    const double m = 1.0 + static_cast<double>(i) / (1 << kLog2TableBits);
    t.log2_mi[i] = i == 0 ? 0.0 : ln_1_2(m) * kInvLn2;
    t.inv_mi[i] = 1.0 / m;
  }
  return t;
}
inline constexpr Log2Table kLog2Table = make_log2_table();
// fast_log2's polynomial: 1/ln 2 times the coefficients of log(1 + r) to r⁴ (the SIMD resolve in
// scene_mesh.cpp evaluates the same one).
inline constexpr double kLog2C1 = 1.4426950408889634, kLog2C2 = -0.7213475204444817,
                        kLog2C3 = 0.48089834696298783, kLog2C4 = -0.36067376022224085;

}  // namespace detail

// log2(x) for normal, finite x > 0 (callers clamp to [2^-128, 2^128]): the exponent from the bits,
// then the mantissa m in [1, 2) split as m = m_i·(1 + r) with m_i = 1 + i/256 from its top 8 bits
// (a 4 KiB table of log2 m_i and 1/m_i), r in [0, 1/256), and log2(1 + r) by its Taylor series to
// r^4 (first omitted term r^5/(5 ln 2) < 3e-13). No division, a short dependency chain; exactly 0
// at m = 1, so exact at every power of two; |error| < 1e-12 (tests check 1e-11).
inline double fast_log2(double x) {
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(x);
  const int e = static_cast<int>((bits >> 52) & 0x7ff) - 1023;
  const std::uint64_t frac = bits & 0x000fffffffffffffULL;
  const int i = static_cast<int>(frac >> (52 - detail::kLog2TableBits));
  const double m = std::bit_cast<double>(frac | 0x3ff0000000000000ULL);
  const double mi = 1.0 + static_cast<double>(i) * (1.0 / (1 << detail::kLog2TableBits));
  const double r = (m - mi) * detail::kLog2Table.inv_mi[i];  // m − mi is exact (same binade)
  // log2(1 + r) = (r − r²/2 + r³/3 − r⁴/4) / ln 2, evaluated as r·(c1 + r·c2) + r³·(c3 + r·c4).
  constexpr double c1 = detail::kLog2C1, c2 = detail::kLog2C2, c3 = detail::kLog2C3, c4 = detail::kLog2C4;
  const double r2 = r * r;
  return static_cast<double>(e) + detail::kLog2Table.log2_mi[i] + (r * (c1 + r * c2) + r2 * r * (c3 + r * c4));
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
