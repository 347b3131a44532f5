#pragma once
// The mesh scene's shading (scene_mesh.h): a visible sample's ray against its triangle's plane,
// the affine texel map and the ray-differential LOD, a batch of samples at a time.
//
// Part of scene_mesh.cpp, split by job: included by it alone, so the renderer stays one
// translation unit (its hot loops inline as before) and these names stay file-local.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>

#include "core/camera.h"
#include "sim/view/render_util.h"
#include "sim/view/simd.h"
#include "sim/view/span_build.h"

namespace vtsim {

namespace {

// One row run of a front face in the resolve: with x the sample's full-resolution column,
// d·n = dn0 + dnx·x (<0 for a front face), t = −kn/(d·n), gu·d = gu0 + gux·x (likewise v), and the
// texel derivatives per pixel step along x and y (the ray-differential terms of lod.h).
struct ShadeRow {
  double dn0, dnx, dny, gu0, gux, guy, gv0, gvx, gvy, kn, cu, cv, inv_a2;
  double far_iz, W, H, bias;  // 1/far; the texture extent, texels (<= kMaxVectorExtent); LOD bias
};
constexpr int kShadeBatch = 64;  // samples per batch: arrays stay in L1
// What a resolved sample is (ViewCounters' reasons, checked in the order of the scalar resolve).
constexpr std::int64_t kSample = 0, kClipped = 1, kBackfacing = 2, kOutside = 3;
struct ShadeBatch {
  alignas(32) std::int64_t cls[kShadeBatch + 4];  // kSample ... kOutside
  alignas(32) std::int64_t u[kShadeBatch + 4];    // texel_index of the texel coordinates (kSample)
  alignas(32) std::int64_t v[kShadeBatch + 4];
  alignas(32) float lod[kShadeBatch + 4];
};
// The batch's texel index needs floor(t) exact as t + 2^52 − 2^52, so t < 2^52: the constructor
// rejects wider textures (configs stop at 2^34, TileKey's range).
constexpr double kMaxVectorExtent = 0x1p52;

// The resolve's arithmetic of the four samples at px[0..3] (full-resolution columns) with depth
// buffer values iz[0..3]: d·n, the continuous texel coordinates and the clamped squared footprint q
// of the LOD rule.
struct ShadeLanes {
  simd::v4d iz, dn, tu, tv, q;
};
template <bool kAniso>
[[gnu::always_inline]] inline void shade_lanes(const ShadeRow& k, const double* px, const double* iz, ShadeLanes& o) {
  using simd::v4d;
  v4d x;
  simd::load4(px, x);
  simd::load4(iz, o.iz);
  const v4d dn = k.dn0 + k.dnx * x;
  const v4d inv_dn = 1.0 / dn;
  const v4d tt = -k.kn * inv_dn;
  const v4d gdu = k.gu0 + k.gux * x, gdv = k.gv0 + k.gvx * x;
  const v4d ru = gdu * inv_dn, rv = gdv * inv_dn;
  const v4d ux = tt * (k.gux - k.dnx * ru), vx = tt * (k.gvx - k.dnx * rv);
  const v4d uy = tt * (k.guy - k.dny * ru), vy = tt * (k.gvy - k.dny * rv);
  const v4d lx2 = ux * ux + vx * vx, ly2 = uy * uy + vy * vy;
  v4d q;
  if constexpr (!kAniso) {  // lod_from_lengths2, lane for lane
    q = lx2 > ly2 ? lx2 : ly2;
  } else {
    const v4d major = lx2 > ly2 ? lx2 : ly2, minor = lx2 > ly2 ? ly2 : lx2, am = major * k.inv_a2;
    q = minor > am ? minor : am;
  }
  const v4d qmin = v4d{} + kMinFootprint2, qmax = v4d{} + kMaxFootprint2;
  q = q >= qmin ? q : qmin;  // also NaN -> min
  o.q = q > qmax ? qmax : q;
  o.dn = dn;
  o.tu = k.cu + tt * gdu;
  o.tv = k.cv + tt * gdv;
}

// Every lane computes exactly the scalar resolve's IEEE operations (texel_index, fast_log2,
// lod_from_lengths2), so the samples are bit-identical to the per-sample code.
template <bool kAniso>
[[gnu::always_inline]] inline void shade_batch_t(const ShadeRow& k, const double* px, const double* iz, int n,
                                                  ShadeBatch& b) {
  using simd::v4d;
  using simd::v4i;
  typedef float v4f __attribute__((vector_size(16)));
  constexpr double two52 = 0x1p52;
  constexpr std::int64_t two52_bits = 0x4330000000000000;
  constexpr double c1 = detail::kLog2C1, c2 = detail::kLog2C2, c3 = detail::kLog2C3, c4 = detail::kLog2C4;
  const auto& tab = detail::kLog2Table;
  for (int j = 0; j < n; j += 4) {
    ShadeLanes l;
    shade_lanes<kAniso>(k, px + j, iz + j, l);
    const v4d izv = l.iz, dn = l.dn, q = l.q, tu = l.tu, tv = l.tv;
    // Classification, in the scalar order: clipped, then edge-on, then outside the texture.
    const v4i in_u = (tu >= 0.0) & (tu < k.W), in_v = (tv >= 0.0) & (tv < k.H);
    v4i cls = (in_u & in_v) ? v4i{} + kSample : v4i{} + kOutside;
    cls = dn < 0.0 ? cls : v4i{} + kBackfacing;
    cls = izv < k.far_iz ? v4i{} + kClipped : cls;
    // texel_index: floor(t) for 0 <= t < 2^52 — t + 2^52 rounds to the nearest integer (ulp 1
    // there), one less where that rounded up; the integer is then the low bits of y + 2^52.
    const auto floor_index = [&](const v4d& t, v4i& out) [[gnu::always_inline]] {
      v4d y = (t + two52) - two52;
      y = y > t ? y - 1.0 : y;
      out = __builtin_bit_cast(v4i, y + two52) - two52_bits;
    };
    // fast_log2(q), lane for lane (q is normal and positive after the clamp).
    const v4i bits = __builtin_bit_cast(v4i, q);
    const v4i ebits = ((bits >> 52) & 0x7ff) | two52_bits;
    const v4d e = __builtin_bit_cast(v4d, ebits) - (two52 + 1023.0);  // exponent − 1023, exact
    const v4i frac = bits & 0x000fffffffffffff;
    const v4i i = frac >> (52 - detail::kLog2TableBits);
    const v4i mbits = frac | 0x3ff0000000000000, ibits = i | two52_bits;
    const v4d m = __builtin_bit_cast(v4d, mbits);
    const v4d mi = 1.0 + (__builtin_bit_cast(v4d, ibits) - two52) * (1.0 / (1 << detail::kLog2TableBits));
    const v4d inv_mi = {tab.inv_mi[i[0]], tab.inv_mi[i[1]], tab.inv_mi[i[2]], tab.inv_mi[i[3]]};
    const v4d log2_mi = {tab.log2_mi[i[0]], tab.log2_mi[i[1]], tab.log2_mi[i[2]], tab.log2_mi[i[3]]};
    const v4d r = (m - mi) * inv_mi;
    const v4d r2 = r * r;
    const v4d lg = e + log2_mi + (r * (c1 + r * c2) + r2 * r * (c3 + r * c4));
    const v4d lod = 0.5 * lg + k.bias;
    const v4f lodf = __builtin_convertvector(lod, v4f);
    v4i u, v;
    // Only a sample's coordinates are used, but every lane is converted: a lane outside the
    // texture (negative, beyond 2^52 or NaN) converts 0 instead, or the integer subtraction
    // overflows (UBSan: a uv of −7e9 on a 2^20 texture).
    floor_index(in_u ? tu : v4d{}, u);
    floor_index(in_v ? tv : v4d{}, v);
    __builtin_memcpy(b.cls + j, &cls, sizeof cls);
    __builtin_memcpy(b.u + j, &u, sizeof u);
    __builtin_memcpy(b.v + j, &v, sizeof v);
    __builtin_memcpy(b.lod + j, &lodf, sizeof lodf);
  }
}
// Reads px[0 .. ceil(n/4)·4) and iz[0 .. ceil(n/4)·4).
VTSIM_CLONES_AVX2 void shade_batch(const ShadeRow& k, const double* px, const double* iz, int n, bool aniso,
                                   ShadeBatch& b) {
  if (aniso) shade_batch_t<true>(k, px, iz, n, b);
  else shade_batch_t<false>(k, px, iz, n, b);
}

// Where the mesh's render_spans writes: the spans so far and the row's open span, which runs of
// different faces continue while their samples stay in its level and block.
struct MeshSpanOut {
  std::vector<ViewSpan>* spans;
  ViewCounters& c;
  const detail::LevelCuts* cuts;
  int levels, block_shift;
  double tw, th;                // texture extent, texels
  std::uint32_t n_samples = 0;  // samples so far: the next span's `first`
  int last_level = 0;
  bool open = false;            // spans.back() may take the next pixel
  detail::SpanBounds k{};       // its test
};

// One row run of a front face in render_spans (n samples from buffer pixel pix0; px and iz padded
// to whole lanes): the arithmetic of shade_batch four lanes at a time, then the open span's test on
// all four (as the plane's span_row). A group whose four samples all stay in the span only widens
// its running box; any other group goes lane by lane with render()'s classification, and a sample
// that leaves the span opens the next one, its level located among the cuts (no logarithm). The
// samples and counters are render()'s: same lanes, same classification order, level and block
// compared as double bounds equivalent to desired_level and the texel index (span_build.h).
template <bool kAniso>
[[gnu::always_inline]] inline void span_run_t(const ShadeRow& k, const double* px, const double* iz, int n,
                                               std::uint32_t pix0, MeshSpanOut& o) {
  detail::RunBox box;
  const auto fold = [&]() __attribute__((always_inline)) {
    if (box.run != 0) o.n_samples += box.fold(o.spans->back());
  };
  for (int j = 0; j < n; j += 4) {
    ShadeLanes l;
    shade_lanes<kAniso>(k, px + j, iz + j, l);
    if (o.open && n - j >= 4 && detail::all_in_span(o.k, l.q, l.tu, l.tv, ((l.iz < k.far_iz) == 0) & (l.dn < 0.0))) {
      box.add(l.tu, l.tv);
      continue;
    }
    fold();
    const int m = n - j < 4 ? n - j : 4;
    for (int i = 0; i < m; ++i) {
      const double dn = l.dn[i], tu = l.tu[i], tv = l.tv[i], q = l.q[i];
      // render()'s classification order: clipped, edge-on, outside the texture.
      if (l.iz[i] < k.far_iz) {
        ++o.c.clipped;
        o.open = false;
        continue;
      }
      if (!(dn < 0.0)) {
        ++o.c.backfacing;
        o.open = false;
        continue;
      }
      const detail::SpanBounds& b = o.k;
      if (o.open && q >= b.q_lo && q < b.q_hi && tu >= b.u_lo && tu < b.u_hi && tv >= b.v_lo && tv < b.v_hi) {
        const std::int64_t u = static_cast<std::int64_t>(tu), v = static_cast<std::int64_t>(tv);  // floors: tu, tv >= 0
        detail::widen(o.spans->back(), u, u, v, v, 1);
        ++o.n_samples;
        continue;
      }
      if (!(tu >= 0.0 && tu < k.W && tv >= 0.0 && tv < k.H)) {
        ++o.c.outside_texture;
        o.open = false;
        continue;
      }
      const std::int64_t u = static_cast<std::int64_t>(tu), v = static_cast<std::int64_t>(tv);
      const int level = detail::cut_level(*o.cuts, q, o.last_level, o.levels);
      o.last_level = level;
      o.spans->push_back(ViewSpan{u, u, v, v, pix0 + static_cast<std::uint32_t>(j + i), 1, o.n_samples, level});
      ++o.n_samples;
      o.k = detail::span_bounds(*o.cuts, level, u, v, o.block_shift, o.tw, o.th);
      o.open = true;
    }
  }
  fold();
}
// Reads px[0 .. ceil(n/4)·4) and iz[0 .. ceil(n/4)·4).
VTSIM_CLONES_AVX2 void span_run(const ShadeRow& k, const double* px, const double* iz, int n, std::uint32_t pix0,
                                bool aniso, MeshSpanOut& o) {
  if (aniso) span_run_t<true>(k, px, iz, n, pix0, o);
  else span_run_t<false>(k, px, iz, n, pix0, o);
}

// For each element of v, the least index of an element with the same bits (exact duplicates
// only: +0 and −0 stay apart, so sharing changes no arithmetic). O(n log n).
template <class V>
std::vector<std::uint32_t> mesh_same_bits(const std::vector<V>& v) {
  constexpr int kLen = V::length();
  const auto less = [&](std::uint32_t a, std::uint32_t b) {
    for (int c = 0; c < kLen; ++c) {
      const auto x = std::bit_cast<std::uint64_t>(v[a][c]), y = std::bit_cast<std::uint64_t>(v[b][c]);
      if (x != y) return x < y;
    }
    return a < b;
  };
  std::vector<std::uint32_t> idx(v.size());
  std::iota(idx.begin(), idx.end(), 0u);
  std::sort(idx.begin(), idx.end(), less);
  std::vector<std::uint32_t> same(v.size());
  for (std::size_t i = 0; i < idx.size(); ++i) {
    const bool dup = i > 0 && std::bit_cast<std::array<std::uint64_t, kLen>>(v[idx[i]]) ==
                                  std::bit_cast<std::array<std::uint64_t, kLen>>(v[idx[i - 1]]);
    same[idx[i]] = dup ? same[idx[i - 1]] : idx[i];
  }
  return same;
}

// A triangle as the depth pass and the resolve use it: corners, the front side
// n = (p1 − p0) × (p2 − p0), and (textured) the gradients of the level-0 texel coordinates
// (texels per metre) and their values at p0. Computed when a triangle is drawn or shaded from the
// shared corners and texture coordinates, with the arithmetic the constructor once stored.
struct TriGeom {
  glm::dvec3 p[3];
  glm::dvec3 n;
  glm::dvec3 gu{}, gv{};
  double tu0 = 0.0, tv0 = 0.0;
};
void tri_corners(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& p2, TriGeom& g) {
  g.p[0] = p0;
  g.p[1] = p1;
  g.p[2] = p2;
  g.n = glm::cross(p1 - p0, p2 - p0);
}
void tri_texel_map(const glm::dvec2& uv0, const glm::dvec2& uv1, const glm::dvec2& uv2, double W, double H, TriGeom& g) {
  // Gradient g of an affine attribute on the triangle's plane from g·e1 = Δ1, g·e2 = Δ2,
  // g·n = 0: g = (Δ1·(e2 × n) + Δ2·(n × e1)) / |n|².
  const glm::dvec3 e1 = g.p[1] - g.p[0], e2 = g.p[2] - g.p[0];
  const double a2 = glm::dot(g.n, g.n);
  const glm::dvec3 a = glm::cross(e2, g.n) / a2, b = glm::cross(g.n, e1) / a2;
  g.gu = ((uv1.x - uv0.x) * W) * a + ((uv2.x - uv0.x) * W) * b;
  g.gv = ((uv1.y - uv0.y) * H) * a + ((uv2.y - uv0.y) * H) * b;
  g.tu0 = uv0.x * W;
  g.tv0 = uv0.y * H;
}

// A triangle's resolve coefficients for one frame: functions affine in the full-resolution pixel
// (px, py) stored as (constant, ∂/∂px, ∂/∂py).
struct Shade {
  glm::dvec3 dn;        // ray · normal
  glm::dvec3 gdu, gdv;  // ray · gu, ray · gv
  double kn = 0.0;      // (camera − p0) · normal
  double cu = 0.0, cv = 0.0;  // texel coordinates of the camera position on the plane's map
};

// The coefficients of triangle t for camera `cam` (its ray d = D0 + px·ddx + py·ddy).
// Triangle t of a scene (corners pos, texture coordinates uvs, texture extent W × H texels).
template <class Tri>
TriGeom tri_geom(const Tri& t, const std::vector<glm::dvec3>& pos, const std::vector<glm::dvec2>& uvs, double W, double H) {
  TriGeom g;
  tri_corners(pos[t.p[0]], pos[t.p[1]], pos[t.p[2]], g);
  if (t.t[0] >= 0)
    tri_texel_map(uvs[static_cast<std::size_t>(t.t[0])], uvs[static_cast<std::size_t>(t.t[1])],
                  uvs[static_cast<std::size_t>(t.t[2])], W, H, g);
  return g;
}

void shade_of(const TriGeom& t, const Camera& cam, Shade& h) {
  const glm::dvec3 o = cam.pos_m, ddx = -cam.left, ddy = -cam.up;
  const glm::dvec3 D0 = cam.ray_dir(0.0, 0.0);
  const glm::dvec3 op = o - t.p[0];
  h.dn = {glm::dot(D0, t.n), glm::dot(ddx, t.n), glm::dot(ddy, t.n)};
  h.kn = glm::dot(op, t.n);
  h.gdu = {glm::dot(D0, t.gu), glm::dot(ddx, t.gu), glm::dot(ddy, t.gu)};
  h.gdv = {glm::dot(D0, t.gv), glm::dot(ddx, t.gv), glm::dot(ddy, t.gv)};
  h.cu = t.tu0 + glm::dot(t.gu, op);
  h.cv = t.tv0 + glm::dot(t.gv, op);
}

// A row's resolve constants of a face with coefficients h at full-resolution row py.
ShadeRow shade_row(const Shade& h, double py, const LodRule& rule, double far_iz, TextureExtent extent) {
  ShadeRow k;
  k.dn0 = h.dn.x + h.dn.z * py;
  k.gu0 = h.gdu.x + h.gdu.z * py;
  k.gv0 = h.gdv.x + h.gdv.z * py;
  k.dnx = h.dn.y;
  k.dny = h.dn.z;
  k.gux = h.gdu.y;
  k.guy = h.gdu.z;
  k.gvx = h.gdv.y;
  k.gvy = h.gdv.z;
  k.kn = h.kn;
  k.cu = h.cu;
  k.cv = h.cv;
  k.inv_a2 = rule.inv_aniso2;
  k.far_iz = far_iz;
  k.W = static_cast<double>(extent.width);
  k.H = static_cast<double>(extent.height);
  k.bias = rule.bias;
  return k;
}

// A row run of a front face in render(): n samples from buffer pixel pix0 (px, iz padded to whole
// lanes) shaded a batch at a time into `out`, the others counted in `c`.
void append_run_samples(const ShadeRow& k, const double* px, const double* iz, int n, std::size_t pix0, bool aniso,
                        ShadeBatch& batch, std::vector<ViewSample>& out, ViewCounters& c) {
  for (int xb = 0; xb < n; xb += kShadeBatch) {
    const int m = std::min(kShadeBatch, n - xb);
    const std::size_t pix = pix0 + static_cast<std::size_t>(xb);
    shade_batch(k, px + xb, iz + xb, m, aniso, batch);
    for (int j = 0; j < m; ++j) {
      switch (batch.cls[j]) {
        case kSample:
          out.push_back(ViewSample{batch.u[j], batch.v[j], batch.lod[j], static_cast<std::uint32_t>(pix + static_cast<std::size_t>(j))});
          break;
        case kClipped: ++c.clipped; break;
        case kBackfacing: ++c.backfacing; break;
        default: ++c.outside_texture; break;
      }
    }
  }
}

}  // namespace

}  // namespace vtsim
