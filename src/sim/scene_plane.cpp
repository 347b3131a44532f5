#include "sim/scene_plane.h"

#include <vector>

#include "sim/render_util.h"

namespace vtsim {

namespace {

constexpr int kChunk = 64;  // pixels per vectorised batch: arrays stay in L1, loops long enough

// Per-pixel values of one batch of a row, computed branch-free so that the compiler vectorises
// them; classification and the logarithm follow in a scalar pass.
struct Batch {
  alignas(32) double dz[kChunk];
  alignas(32) double t[kChunk];
  alignas(32) double tu[kChunk];  // continuous level-0 texel coordinates of the hit
  alignas(32) double tv[kChunk];
  alignas(32) double q[kChunk];   // squared footprint for the LOD rule, clamped
};

// Branch-free per-pixel arithmetic of a batch (vectorised by the compiler).
template <bool kAniso>
void fill_batch(Batch& b, const double* a, int n, const glm::dvec3& row, const glm::dvec3& L, const glm::dvec3& U,
                double ox, double oy, double oz, double tpm, double tpm2, double inv_a2) {
  const double Lx = L.x, Ly = L.y, Lz = L.z, Ux = U.x, Uy = U.y, Uz = U.z;
  const double rx = row.x, ry = row.y, rz = row.z;
  for (int j = 0; j < n; ++j) {
    const double dx = rx + a[j] * Lx, dy = ry + a[j] * Ly, dz = rz + a[j] * Lz;
    const double r = 1.0 / dz;
    const double t = -oz * r;
    const double kx = Lz * r, ky = Uz * r;
    const double ax = kx * dx - Lx, ay = kx * dy - Ly;
    const double bx = ky * dx - Ux, by = ky * dy - Uy;
    const double s = t * t * tpm2;
    const double lx2 = s * (ax * ax + ay * ay), ly2 = s * (bx * bx + by * by);
    const double major = lx2 > ly2 ? lx2 : ly2;
    double q = major;
    if constexpr (kAniso) {
      const double minor = lx2 > ly2 ? ly2 : lx2, am = major * inv_a2;
      q = minor > am ? minor : am;
    }
    q = q >= kMinFootprint2 ? q : kMinFootprint2;  // also NaN -> min (as lod_from_lengths2)
    q = q > kMaxFootprint2 ? kMaxFootprint2 : q;
    b.dz[j] = dz;
    b.t[j] = t;
    b.tu[j] = (ox + t * dx) * tpm;
    b.tv[j] = (oy + t * dy) * tpm;
    b.q[j] = q;
  }
}

}  // namespace

// The plane is the hot case of the benchmark target (≈ 7.7 ns per sample at divisor 8), so the
// ray differentials are specialised for n = +z: with d the sample's ray, r = 1/d.z and the hit
// at t = −o.z·r, one pixel right moves the hit by t·(−L + (L.z·r)·d) and one pixel down by
// t·(−U + (U.z·r)·d) (lod.h, Igehy's plane differential with n = z). Each sample is computed from
// its own row and column only, so a buffer of any divisor reproduces divisor 1's values bit for
// bit. Rows whose two end rays both miss the plane are sky throughout (d.z is linear along a row
// and its rounded evaluation monotone) and cost O(1).
void PlaneScene::render(const Camera& cam, const ViewParams& p, ViewBuffer& out) const {
  detail::begin_frame(cam, p, out);
  const LodRule rule = detail::lod_rule(p);
  const double oz = cam.pos_m.z - z_;
  const double ox = cam.pos_m.x - tex_.x0_m, oy = cam.pos_m.y - tex_.y0_m;
  const double tpm = tex_.texels_per_m, tpm2 = tpm * tpm;
  const double f = cam.focal_px;
  const double t_near = p.near_m / f, t_far = p.far_m / f;  // view depth = t·focal_px
  const double Lz = cam.left.z;
  const double tw = static_cast<double>(tex_.extent.width), th = static_cast<double>(tex_.extent.height);
  const int div = p.divisor, bw = out.width, bh = out.height;
  const bool aniso = rule.anisotropic;
  const double inv_a2 = rule.inv_aniso2;

  thread_local std::vector<double> col;  // cx − px of each buffer column
  col.resize(static_cast<std::size_t>(bw));
  for (int bx = 0; bx < bw; ++bx) col[static_cast<std::size_t>(bx)] = cam.cx - sample_pos(bx, div, cam.width);
  thread_local Batch b;

  ViewCounters c;
  for (int by = 0; by < bh; ++by) {
    const double py = sample_pos(by, div, cam.height);
    const glm::dvec3 row = f * cam.fwd + (cam.cy - py) * cam.up;
    const double dz_first = row.z + col[0] * Lz, dz_last = row.z + col[static_cast<std::size_t>(bw - 1)] * Lz;
    if (oz != 0.0 && dz_first * oz >= 0.0 && dz_last * oz >= 0.0) {
      c.sky += static_cast<std::uint64_t>(bw);
      continue;
    }
    for (int x0 = 0; x0 < bw; x0 += kChunk) {
      const int n = bw - x0 < kChunk ? bw - x0 : kChunk;
      const double* a = col.data() + x0;
      if (aniso) fill_batch<true>(b, a, n, row, cam.left, cam.up, ox, oy, oz, tpm, tpm2, inv_a2);
      else fill_batch<false>(b, a, n, row, cam.left, cam.up, ox, oy, oz, tpm, tpm2, inv_a2);
      for (int j = 0; j < n; ++j) {
        const double dz = b.dz[j], t = b.t[j];
        if (!(dz * oz < 0.0)) {  // parallel, pointing away from the plane, or camera on it
          if (oz == 0.0 && dz != 0.0) ++c.clipped;  // hit at depth 0 < near
          else ++c.sky;
          continue;
        }
        if (!(t >= t_near && t <= t_far)) {
          ++c.clipped;
          continue;
        }
        if (oz < 0.0) {  // camera below the plane sees its back
          ++c.backfacing;
          continue;
        }
        const double tu = b.tu[j], tv = b.tv[j];
        if (!(tu >= 0.0 && tu < tw && tv >= 0.0 && tv < th)) {
          ++c.outside_texture;
          continue;
        }
        std::int64_t u = static_cast<std::int64_t>(tu), v = static_cast<std::int64_t>(tv);
        if (u >= tex_.extent.width) u = tex_.extent.width - 1;  // within an ulp of W above 2^53
        if (v >= tex_.extent.height) v = tex_.extent.height - 1;
        const double lod = 0.5 * fast_log2(b.q[j]) + rule.bias;
        out.samples.push_back(ViewSample{u, v, static_cast<float>(lod), static_cast<std::uint32_t>(by * bw + x0 + j)});
      }
    }
  }
  out.counters = c;
}

}  // namespace vtsim
