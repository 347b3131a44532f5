#pragma once
// The mesh scene's depth pass (scene_mesh.h): the camera in the rasteriser's terms, the frustum,
// and the culling and drawing of the hierarchy's chunks and their triangles.
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

#include "sim/view/scene_mesh_bvh.h"
#include "sim/view/scene_mesh_raster.h"

namespace vtsim {

namespace {

// The part of a triangle between view depth near/1024 and near is rasterised only to tell
// "clipped" from "sky" in the counters; nearer than that it is ignored (projection blows up).
constexpr double kNearFlagFraction = 1.0 / 1024.0;
// Relative margin of the occlusion test: a triangle's rasterised 1/z exceeds the exact bound of
// its chunk's box only by rounding (a few ulps, far more for a sliver whose plane equation
// cancels); 2^-20 leaves 2^32 ulps.
constexpr double kOccludeMargin = 0x1p-20;

// The depth pass of one render: the camera in the rasteriser's terms (x right, y up, z view
// depth), its frustum, and the steps per chunk and per triangle. Draws into a scratch that has
// begun the render (Scratch::begin).
struct DepthPass {
  glm::dvec3 o, F, R, U;  // camera position, world metres; its forward, right and up axes
  double cx, cy, f;       // principal point and focal length, full-resolution pixels
  double near, zflag;     // the near plane and near·kNearFlagFraction, view depth in metres
  int div, bw, bh;        // divisor; buffer size, samples
  bool cull, skip_back;   // occlusion culling; back faces skipped (MeshScene::skips_back_faces)
  glm::dvec3 planes[5];   // frustum planes through o at the image border, inward normals
  const Camera& camera;
  const std::uint32_t* src;  // per triangle, its index in the Mesh (the depth test's tie rule)
  Scratch& s;

  DepthPass(const Camera& cam, const ViewParams& p, Scratch& scr, bool occlusion_culling, bool skip_back_faces,
            const std::uint32_t* mesh_index)
      : o(cam.pos_m), F(cam.fwd), R(-cam.left), U(cam.up), cx(cam.cx), cy(cam.cy), f(cam.focal_px), near(p.near_m),
        zflag(p.near_m * kNearFlagFraction), div(p.divisor), bw(scr.bw), bh(scr.bh), cull(occlusion_culling),
        skip_back(skip_back_faces),
        planes{
            F,                                        // in front of the camera
            R + (cam.cx / f) * F,                     // right of the left border: x >= −(cx/f)·z
            -R + ((cam.width - cam.cx) / f) * F,      // left of the right border
            -U + (cam.cy / f) * F,                    // below the top border: y <= (cy/f)·z
            U + ((cam.height - cam.cy) / f) * F,      // above the bottom border
        },
        camera(cam), src(mesh_index), s(scr) {}

  // Whether box [lo, hi] may reach into the frustum (its corner farthest along each plane's normal
  // is inside all five).
  bool in_frustum(const glm::dvec3& lo, const glm::dvec3& hi) const {
    for (const glm::dvec3& pl : planes) {
      const glm::dvec3 corner(pl.x >= 0.0 ? hi.x : lo.x, pl.y >= 0.0 ? hi.y : lo.y, pl.z >= 0.0 ? hi.z : lo.z);
      if (glm::dot(corner - o, pl) < 0.0) return false;
    }
    return true;
  }

  // The least view depth of box [lo, hi], metres (a linear function is least at a corner).
  double least_depth(const glm::dvec3& lo, const glm::dvec3& hi) const {
    const glm::dvec3 nearest(F.x >= 0.0 ? lo.x : hi.x, F.y >= 0.0 ? lo.y : hi.y, F.z >= 0.0 ? lo.z : hi.z);
    return glm::dot(nearest - o, F);
  }

  // Whether box [lo, hi], at least view depth zmin > 0, lies behind what is drawn at every sample
  // its projection can cover (also when it covers none): then none of its triangles can win a
  // sample. O(log buffer side + tiles its projection spans). kOccludeMargin covers the rasteriser's rounding of 1/z against the box's exact bound.
  bool occluded(const glm::dvec3& lo, const glm::dvec3& hi, double zmin) const {
    double X0 = INFINITY, X1 = -INFINITY, Y0 = INFINITY, Y1 = -INFINITY;
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 q = glm::dvec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z) - o;
      const double iz = 1.0 / glm::dot(q, F);
      const double X = cx + f * glm::dot(q, R) * iz, Y = cy - f * glm::dot(q, U) * iz;
      X0 = std::min(X0, X);
      X1 = std::max(X1, X);
      Y0 = std::min(Y0, Y);
      Y1 = std::max(Y1, Y);
    }
    // A box whose projection holds no sample position (a far one between the samples) cannot
    // cover any either; the 2^-20 relative margin covers the rounding of the projections.
    const auto none_within = [](const double* pos, int n, double a, double b, double m) {
      const double* it = std::lower_bound(pos, pos + n, a - m);
      return it == pos + n || *it > b + m;
    };
    const double mx = (std::fabs(X0) + std::fabs(X1) + f) * 0x1p-20, my = (std::fabs(Y0) + std::fabs(Y1) + f) * 0x1p-20;
    if (none_within(s.sx.data(), bw, X0, X1, mx) || none_within(s.sy.data(), bh, Y0, Y1, my)) return true;
    int x0, x1, y0, y1;
    sample_range(X0, X1, div, bw, x0, x1);
    sample_range(Y0, Y1, div, bh, y0, y1);
    // A sample of the rectangle that is not nearer (most often sky beside or above the box: the
    // rectangle of a wide box seen from a street holds far more than the box's hexagon) counts
    // only if its ray meets the box (slab test, Kay & Kajiya 1986): a triangle in the box covers a
    // sample only if the sample's ray meets the triangle. The box grows by 2^-20 of its distance
    // and size, far beyond the rounding of the rasteriser's projections.
    const glm::dvec3 far_corner = glm::max(glm::abs(lo - o), glm::abs(hi - o));
    const double grow = (std::max({far_corner.x, far_corner.y, far_corner.z}) + 1.0) * 0x1p-20;
    const glm::dvec3 blo = lo - grow, bhi = hi + grow;
    const auto reaches = [&](int x, int y) {
      double t0 = 0.0, t1 = INFINITY;
      return detail::clip_ray_to_box(o, camera.ray_dir(s.sx[static_cast<std::size_t>(x)], s.sy[static_cast<std::size_t>(y)]), blo,
                                     bhi, t0, t1);
    };
    return s.all_nearer_where(x0, x1, y0, y1, (1.0 / zmin) * (1.0 + kOccludeMargin), reaches);
  }

  void project(const CV* poly, int n, PV* out) const {
    for (int c = 0; c < n; ++c) {
      const double iz = 1.0 / poly[c].z;
      out[c] = PV{cx + f * poly[c].x * iz, cy - f * poly[c].y * iz, iz};
    }
  }

  // Triangle k (corners p, world metres; n its front side): clip at near, project,
  // occlusion-test, rasterise its depth; the part between near/1024 and near only as a flag.
  void draw(const glm::dvec3 (&p)[3], const glm::dvec3& n, std::uint32_t k) const {
    ++s.stats.triangles_visited;
    const bool front = glm::dot(o - p[0], n) > 0.0;
    if (!front && skip_back) {
      ++s.stats.back_faces_skipped;
      return;
    }
    CV cv[3];
    bool all_near = true, any_flag = false;
    for (int c = 0; c < 3; ++c) {
      const glm::dvec3 q = p[c] - o;
      cv[c] = CV{glm::dot(q, R), glm::dot(q, U), glm::dot(q, F)};
      all_near = all_near && cv[c].z >= near;
      any_flag = any_flag || cv[c].z >= zflag;
    }
    if (!any_flag) return;  // wholly behind the camera or nearer than near/1024
    const std::uint32_t tag = front ? k : (k | kBackBit);
    PV pv[5];
    if (all_near) {
      project(cv, 3, pv);
      if (cull) {
        // The chunk test at triangle granularity (same bound and margin): of the ~3,700
        // triangles in the chunks a street-level town view draws, ~40 win a sample.
        int x0, x1, y0, y1;
        sample_range(std::min({pv[0].X, pv[1].X, pv[2].X}), std::max({pv[0].X, pv[1].X, pv[2].X}), div, bw, x0, x1);
        sample_range(std::min({pv[0].Y, pv[1].Y, pv[2].Y}), std::max({pv[0].Y, pv[1].Y, pv[2].Y}), div, bh, y0, y1);
        const double tz = std::min({cv[0].z, cv[1].z, cv[2].z});
        if (s.all_nearer(x0, x1, y0, y1, (1.0 / tz) * (1.0 + kOccludeMargin))) {
          ++s.stats.triangles_occluded;
          return;
        }
      }
      ++s.stats.triangles_rasterised;
      raster_poly(pv, 3, tag, true, div, bw, bh, src, s);
      return;
    }
    CV clip_a[4], clip_b[5], tmp[4];
    const int na = clip_poly(cv, 3, near, true, clip_a);
    if (na >= 3) {
      ++s.stats.triangles_rasterised;
      project(clip_a, na, pv);
      raster_poly(pv, na, tag, true, div, bw, bh, src, s);
    }
    const int nt = clip_poly(cv, 3, near, false, tmp);
    const int nb = nt >= 3 ? clip_poly(tmp, nt, zflag, true, clip_b) : 0;
    if (nb >= 3) {
      project(clip_b, nb, pv);
      raster_poly(pv, nb, 0, false, div, bw, bh, src, s);
    }
  }
};

}  // namespace

}  // namespace vtsim
