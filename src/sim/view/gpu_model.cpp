#include "sim/view/gpu_model.h"

#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <vector>

#include <glm/geometric.hpp>

#include "sim/view/render_util.h"
#include "sim/view/scene.h"
#include "sim/view/scene_mesh.h"
#include "sim/view/scene_plane.h"

namespace vtsim {

void IScene::surface_at(const Camera&, const ViewParams&, double, double, SurfaceHit&) const {
  throw std::logic_error("surface_at: the GPU feedback model does not draw this scene");
}

void feedback_tile_offset(FeedbackSampling mode, long long frame, int divisor, int& ox, int& oy) {
  if (mode == FeedbackSampling::middle || divisor <= 1) {
    ox = oy = divisor / 2;
    return;
  }
  const long long n = static_cast<long long>(divisor) * divisor;
  long long s = static_cast<long long>(0.618 * static_cast<double>(n));
  while (std::gcd(s, n) != 1) ++s;
  const long long f = frame % n;
  const long long j = (f < 0 ? f + n : f) * s % n;
  ox = static_cast<int>(j % divisor);
  oy = static_cast<int>(j / divisor);
}

// The ground plane z = z0 (PlaneScene's classification: PlaneFrame::classify in scene_plane.cpp).
void PlaneScene::surface_at(const Camera& cam, const ViewParams& p, double px, double py, SurfaceHit& out) const {
  out = SurfaceHit{};
  const glm::dvec3 d = cam.ray_dir(px, py);
  const double oz = cam.pos_m.z - z_;
  if (!(d.z * oz < 0.0)) {
    out.kind = oz == 0.0 && d.z != 0.0 ? SurfaceHit::clipped : SurfaceHit::none;
    return;
  }
  const double t = -oz / d.z, f = cam.focal_px;
  if (!(t >= p.near_m / f && t <= p.far_m / f)) {
    out.kind = SurfaceHit::clipped;
    return;
  }
  if (oz < 0.0) {
    out.kind = SurfaceHit::backfacing;
    return;
  }
  const double tpm = tex_.texels_per_m;
  out.p = cam.pos_m + t * d;
  out.n = glm::dvec3(0.0, 0.0, 1.0);
  out.tu = (cam.pos_m.x - tex_.x0_m + t * d.x) * tpm;
  out.tv = (cam.pos_m.y - tex_.y0_m + t * d.y) * tpm;
  out.gu = glm::dvec3(tpm, 0.0, 0.0);
  out.gv = glm::dvec3(0.0, tpm, 0.0);
  std::int64_t u = 0, v = 0;
  out.kind = detail::texel_index(out.tu, tex_.extent.width, u) && detail::texel_index(out.tv, tex_.extent.height, v)
                 ? SurfaceHit::sample
                 : SurfaceHit::outside_texture;
}

// The nearest triangle along the ray through the chunk hierarchy (the rasteriser's answer without
// its culling: nearest depth at or beyond the near plane, ties to the triangle first in the Mesh).
void MeshScene::surface_at(const Camera& cam, const ViewParams& p, double px, double py, SurfaceHit& out) const {
  out = SurfaceHit{};
  const glm::dvec3 o = cam.pos_m, d = cam.ray_dir(px, py);
  const double f = cam.focal_px, t_near = p.near_m / f, t_far = p.far_m / f;
  double best = std::numeric_limits<double>::infinity();
  std::uint32_t best_src = 0;
  std::size_t best_tri = SIZE_MAX;
  bool clipped = false;
  const glm::dvec3 inv(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
  thread_local std::vector<std::uint32_t> stack(256);
  int sp = 0;
  if (!chunk_tree_.empty()) stack[static_cast<std::size_t>(sp++)] = 0;
  while (sp > 0) {
    const std::uint32_t ni = stack[static_cast<std::size_t>(--sp)];
    const Node& n = chunk_tree_[ni];
    double t0 = 0.0, t1 = best;
    bool in = true;
    for (int k = 0; k < 3 && in; ++k) {
      double a = (static_cast<double>(n.lo[k]) - o[k]) * inv[k], b = (static_cast<double>(n.hi[k]) - o[k]) * inv[k];
      if (std::isnan(a) || std::isnan(b)) continue;  // d[k] = 0 with o on a slab face: keep
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b);
      in = t0 <= t1;
    }
    if (!in) continue;
    if (n.right != 0) {  // an inner node (a leaf's right is 0: the root is nobody's child)
      if (sp + 2 > static_cast<int>(stack.size())) stack.resize(stack.size() * 2);
      stack[static_cast<std::size_t>(sp++)] = n.right;
      stack[static_cast<std::size_t>(sp++)] = ni + 1;
      continue;
    }
    for (std::uint32_t ti = chunk_first_[n.item]; ti < chunk_first_[n.item + 1]; ++ti) {
      const Tri& tr = tris_[ti];
      const glm::dvec3 p0 = positions_[tr.p[0]], e1 = positions_[tr.p[1]] - p0, e2 = positions_[tr.p[2]] - p0;
      const glm::dvec3 pv = glm::cross(d, e2);
      const double det = glm::dot(e1, pv);
      if (det == 0.0) continue;
      const double id = 1.0 / det;
      const glm::dvec3 s = o - p0;
      const double bu = glm::dot(s, pv) * id;
      if (bu < 0.0 || bu > 1.0) continue;
      const glm::dvec3 qv = glm::cross(s, e1);
      const double bv = glm::dot(d, qv) * id;
      if (bv < 0.0 || bu + bv > 1.0) continue;
      const double t = glm::dot(e2, qv) * id;
      if (!(t > 0.0)) continue;
      if (t < t_near) {
        clipped = true;
        continue;
      }
      if (t < best || (t == best && src_[ti] < best_src)) {
        best = t;
        best_src = src_[ti];
        best_tri = ti;
      }
    }
  }
  if (best_tri == SIZE_MAX) {
    out.kind = clipped ? SurfaceHit::clipped : SurfaceHit::none;
    return;
  }
  if (best > t_far) {
    out.kind = SurfaceHit::clipped;
    return;
  }
  const Tri& tr = tris_[best_tri];
  const glm::dvec3 p0 = positions_[tr.p[0]], e1 = positions_[tr.p[1]] - p0, e2 = positions_[tr.p[2]] - p0;
  out.n = glm::cross(e1, e2);
  out.p = o + best * d;
  if (!(glm::dot(d, out.n) < 0.0)) {
    out.kind = SurfaceHit::backfacing;
    return;
  }
  if (tr.t[0] < 0) {
    out.kind = SurfaceHit::untextured;
    return;
  }
  const double W = static_cast<double>(extent_.width), H = static_cast<double>(extent_.height);
  const glm::dvec2 t0 = uvs_[static_cast<std::size_t>(tr.t[0])] * glm::dvec2(W, H);
  const glm::dvec2 d1 = uvs_[static_cast<std::size_t>(tr.t[1])] * glm::dvec2(W, H) - t0;
  const glm::dvec2 d2 = uvs_[static_cast<std::size_t>(tr.t[2])] * glm::dvec2(W, H) - t0;
  // Gradients g on the plane with g·e1 = Δ1, g·e2 = Δ2: g = a·e1 + b·e2 (Gram system).
  const double g11 = glm::dot(e1, e1), g12 = glm::dot(e1, e2), g22 = glm::dot(e2, e2);
  const double det = g11 * g22 - g12 * g12;
  const auto grad = [&](double a1, double a2) {
    const double a = (a1 * g22 - a2 * g12) / det, b = (a2 * g11 - a1 * g12) / det;
    return a * e1 + b * e2;
  };
  out.gu = grad(d1.x, d2.x);
  out.gv = grad(d1.y, d2.y);
  const glm::dvec3 r = out.p - p0;
  out.tu = t0.x + glm::dot(out.gu, r);
  out.tv = t0.y + glm::dot(out.gv, r);
  std::int64_t u = 0, v = 0;
  out.kind = detail::texel_index(out.tu, extent_.width, u) && detail::texel_index(out.tv, extent_.height, v)
                 ? SurfaceHit::sample
                 : SurfaceHit::outside_texture;
}

void render_gpu_model(const IScene& scene, const Camera& cam, const ViewParams& params, int ox, int oy, ViewBuffer& out) {
  detail::begin_frame(cam, params, out);
  const int div = params.divisor;
  if (ox < 0 || oy < 0 || ox >= div || oy >= div) throw std::invalid_argument("render_gpu_model: tile offset outside the tile");
  LodRule rule = detail::lod_rule(params);
  rule.bias -= std::log2(static_cast<double>(div));
  const int bw = out.width, bh = out.height;
  const glm::dvec3 o = cam.pos_m;
  // Texel coordinates of the ray through (qx, qy) on the plane of hit h (GL's helper invocation).
  const auto texel_on = [&](const SurfaceHit& h, double qx, double qy, double& tu, double& tv) {
    const glm::dvec3 dq = cam.ray_dir(qx, qy);
    const double t = glm::dot(h.p - o, h.n) / glm::dot(dq, h.n);
    const glm::dvec3 r = o + t * dq - h.p;
    tu = h.tu + glm::dot(h.gu, r);
    tv = h.tv + glm::dot(h.gv, r);
  };
  ViewCounters& c = out.counters;
  SurfaceHit h;
  for (int by = 0; by < bh; ++by) {
    const double py = gpu_sample_pos(by, div, oy), py_partner = gpu_sample_pos(by ^ 1, div, oy);
    for (int bx = 0; bx < bw; ++bx) {
      const double px = gpu_sample_pos(bx, div, ox);
      scene.surface_at(cam, params, px, py, h);
      switch (h.kind) {
        case SurfaceHit::none: ++c.sky; continue;
        case SurfaceHit::clipped: ++c.clipped; continue;
        case SurfaceHit::backfacing: ++c.backfacing; continue;
        case SurfaceHit::outside_texture: ++c.outside_texture; continue;
        case SurfaceHit::untextured: ++c.untextured; continue;
        case SurfaceHit::sample: break;
      }
      double ux, vx, uy, vy;
      texel_on(h, gpu_sample_pos(bx ^ 1, div, ox), py, ux, vx);
      texel_on(h, px, py_partner, uy, vy);
      ux -= h.tu;
      vx -= h.tv;
      uy -= h.tu;
      vy -= h.tv;
      const double lod = lod_from_lengths2(ux * ux + vx * vx, uy * uy + vy * vy, rule);
      std::int64_t u = 0, v = 0;
      detail::texel_index(h.tu, scene.texture().width, u);
      detail::texel_index(h.tv, scene.texture().height, v);
      out.samples.push_back(ViewSample{u, v, static_cast<float>(lod), static_cast<std::uint32_t>(by * bw + bx)});
    }
  }
}

namespace gpu_model_detail {

class GpuModelScene final : public IScene {
 public:
  explicit GpuModelScene(std::unique_ptr<IScene> inner) : inner_(std::move(inner)) {}
  TextureExtent texture() const override { return inner_->texture(); }
  void render(const Camera& cam, const ViewParams& params, ViewBuffer& out) const override {
    const int o = params.divisor / 2;
    render_gpu_model(*inner_, cam, params, params.sample_ox < 0 ? o : params.sample_ox,
                     params.sample_oy < 0 ? o : params.sample_oy, out);
  }
  void surface_at(const Camera& cam, const ViewParams& params, double px, double py, SurfaceHit& hit) const override {
    inner_->surface_at(cam, params, px, py, hit);
  }
  std::vector<std::string> load_warnings() const override { return inner_->load_warnings(); }

 private:
  std::unique_ptr<IScene> inner_;
};

}  // namespace gpu_model_detail

std::unique_ptr<IScene> make_gpu_model_scene(std::unique_ptr<IScene> inner) {
  return std::make_unique<gpu_model_detail::GpuModelScene>(std::move(inner));
}

}  // namespace vtsim
