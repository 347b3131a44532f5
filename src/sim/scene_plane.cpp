#include "sim/scene_plane.h"

#include "sim/render_util.h"

namespace vtsim {

// The plane is the hot case of the benchmark target (≈ 7.7 ns per sample at divisor 8), so the
// ray differentials are specialised for n = +z: with d the sample's ray, r = 1/d.z and the hit
// at t = −o.z·r, one pixel right moves the hit by t·(−L + (L.z·r)·d) and one pixel down by
// t·(−U + (U.z·r)·d) (lod.h, Igehy's plane differential with n = z). Each sample is computed from
// its own pixel position, so a buffer of any divisor reproduces divisor 1's values bit for bit.
void PlaneScene::render(const Camera& cam, const ViewParams& p, ViewBuffer& out) const {
  detail::begin_frame(cam, p, out);
  const LodRule rule = detail::lod_rule(p);
  const double oz = cam.pos_m.z - z_;
  const double ox = cam.pos_m.x - tex_.x0_m, oy = cam.pos_m.y - tex_.y0_m;
  const double tpm = tex_.texels_per_m, tpm2 = tpm * tpm;
  const double f = cam.focal_px;
  const double t_near = p.near_m / f, t_far = p.far_m / f;  // view depth = t·focal_px
  const glm::dvec3 L = cam.left, U = cam.up;
  const std::int64_t tw = tex_.extent.width, th = tex_.extent.height;
  const int div = p.divisor, bw = out.width, bh = out.height;
  ViewCounters c;
  for (int by = 0; by < bh; ++by) {
    const double py = sample_pos(by, div, cam.height);
    const glm::dvec3 row = f * cam.fwd + (cam.cy - py) * U;
    const double ky = U.z, uxr = U.x, uyr = U.y;
    for (int bx = 0; bx < bw; ++bx) {
      const double a = cam.cx - sample_pos(bx, div, cam.width);
      const double dx = row.x + a * L.x, dy = row.y + a * L.y, dz = row.z + a * L.z;
      if (!(dz * oz < 0.0)) {  // parallel, pointing away from the plane, or camera on it
        if (oz == 0.0 && dz != 0.0) ++c.clipped;  // hit at depth 0 < near
        else ++c.sky;
        continue;
      }
      const double r = 1.0 / dz;
      const double t = -oz * r;  // > 0
      if (!(t >= t_near && t <= t_far)) {
        ++c.clipped;
        continue;
      }
      if (oz < 0.0) {  // camera below the plane sees its back
        ++c.backfacing;
        continue;
      }
      std::int64_t u, v;
      if (!detail::texel_index((ox + t * dx) * tpm, tw, u) ||
          !detail::texel_index((oy + t * dy) * tpm, th, v)) {
        ++c.outside_texture;
        continue;
      }
      const double kx = L.z * r, kyr = ky * r;
      const double ax = kx * dx - L.x, ay = kx * dy - L.y;
      const double bx2 = kyr * dx - uxr, by2 = kyr * dy - uyr;
      const double s = t * t * tpm2;
      const double lod = lod_from_lengths2(s * (ax * ax + ay * ay), s * (bx2 * bx2 + by2 * by2), rule);
      out.samples.push_back(ViewSample{u, v, static_cast<float>(lod),
                                       static_cast<std::uint32_t>(by * bw + bx)});
    }
  }
  out.counters = c;
}

}  // namespace vtsim
