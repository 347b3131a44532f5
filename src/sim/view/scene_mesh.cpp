#include "sim/view/scene_mesh.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>

#include "core/error.h"
#include "sim/view/render_util.h"
#include "sim/view/simd.h"
#include "sim/view/span_build.h"

// The renderer's parts, by job (each included here alone):
#include "sim/view/scene_mesh_bvh.h"
#include "sim/view/scene_mesh_shade.h"
#include "sim/view/scene_mesh_raster.h"
#include "sim/view/scene_mesh_depth.h"

namespace vtsim {

MeshScene::MeshScene(const Mesh& mesh, TextureExtent extent) : extent_(extent) {
  if (extent.width < 1 || extent.height < 1) throw InputError("texture", "extent must be at least 1×1");
  if (static_cast<double>(extent.width) > kMaxVectorExtent || static_cast<double>(extent.height) > kMaxVectorExtent)
    throw InputError("texture", "extent must be at most 2^52 texels a side");
  if (mesh.tris.empty()) throw InputError("mesh", "no triangles");
  if (mesh.tris.size() >= kBackBit) throw InputError("mesh", "more than 2^31 − 1 triangles");
  for (std::size_t k = 0; k < mesh.tris.size(); ++k) {
    const Mesh::Tri& mt = mesh.tris[k];
    const std::string where = "mesh triangle " + std::to_string(k);
    glm::dvec3 p[3];
    for (int c = 0; c < 3; ++c) {
      if (mt.p[c] >= mesh.positions.size()) throw InputError(where, "vertex index out of range");
      p[c] = mesh.positions[mt.p[c]];
      if (!std::isfinite(p[c].x) || !std::isfinite(p[c].y) || !std::isfinite(p[c].z))
        throw InputError(where, "vertex is not finite");
    }
    const glm::dvec3 n = glm::cross(p[1] - p[0], p[2] - p[0]);
    const double a2 = glm::dot(n, n);
    if (!(a2 > 0.0) || !std::isfinite(a2)) throw InputError(where, "zero-area or non-finite triangle");
    if (mt.t[0] >= 0)
      for (int c = 0; c < 3; ++c) {
        if (mt.t[c] < 0 || static_cast<std::size_t>(mt.t[c]) >= mesh.uvs.size())
          throw InputError(where, "texture coordinate index out of range");
        const glm::dvec2 uv = mesh.uvs[static_cast<std::size_t>(mt.t[c])];
        if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) throw InputError(where, "uv is not finite");
      }
  }
  for (std::size_t k = 0; k < mesh.solids.size(); ++k) {
    const Mesh::Box& b = mesh.solids[k];
    if (!(b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z))
      throw InputError("mesh solid " + std::to_string(k), "bounds are NaN or lo > hi");
  }
  // Spatial order (Morton code of the centroid in the mesh's box) so that chunks are compact.
  const std::size_t nt = mesh.tris.size();
  const auto corner = [&](std::size_t k, int c) -> const glm::dvec3& { return mesh.positions[mesh.tris[k].p[c]]; };
  glm::dvec3 lo = corner(0, 0), hi = lo;
  for (std::size_t k = 0; k < nt; ++k)
    for (int c = 0; c < 3; ++c) {
      lo = glm::min(lo, corner(k, c));
      hi = glm::max(hi, corner(k, c));
    }
  const glm::dvec3 ext = glm::max(hi - lo, glm::dvec3(1e-300));
  std::vector<std::uint32_t> code(nt);
  for (std::size_t k = 0; k < nt; ++k) code[k] = morton_code((corner(k, 0) + corner(k, 1) + corner(k, 2)) / 3.0, lo, ext);
  std::vector<std::uint32_t> order(nt);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return code[a] < code[b]; });
  std::vector<std::uint32_t> sorted_code(nt);  // of the triangle at each position
  for (std::size_t k = 0; k < nt; ++k) sorted_code[k] = code[order[k]];
  code = {};
  // Shared corners and texture coordinates: one copy of each bit pattern, numbered in the order
  // the sorted triangles first use them (a chunk's corners lie together).
  const std::vector<std::uint32_t> pos_same = mesh_same_bits(mesh.positions), uv_same = mesh_same_bits(mesh.uvs);
  std::vector<std::uint32_t> pos_new(mesh.positions.size(), kNoTri), uv_new(mesh.uvs.size(), kNoTri);
  tris_.reserve(nt);
  src_ = order;
  for (const std::uint32_t k : order) {
    const Mesh::Tri& mt = mesh.tris[k];
    Tri t;
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t q = pos_same[mt.p[c]];
      if (pos_new[q] == kNoTri) {
        pos_new[q] = static_cast<std::uint32_t>(positions_.size());
        positions_.push_back(mesh.positions[q]);
      }
      t.p[c] = pos_new[q];
      if (mt.t[0] < 0) continue;
      const std::uint32_t u = uv_same[static_cast<std::size_t>(mt.t[c])];
      if (uv_new[u] == kNoTri) {
        uv_new[u] = static_cast<std::uint32_t>(uvs_.size());
        uvs_.push_back(mesh.uvs[u]);
      }
      t.t[c] = static_cast<std::int32_t>(uv_new[u]);
    }
    tris_.push_back(t);
  }
  positions_.shrink_to_fit();
  uvs_.shrink_to_fit();
  {
    // The chunks and their tree, which orders the triangles within ranges of kSahRange.
    order = {};
    chunk_tree_.reserve(nt / 4 + 1);  // at most 4n/17 nodes: a leaf's parent holds > 16 triangles
    chunk_first_.reserve(nt / 8 + 2);
    SahRange sah;
    chunk_bvh_build(
        chunk_tree_, chunk_first_, sorted_code.data(), 0, static_cast<std::uint32_t>(nt), sah,
        [&](std::uint32_t k, glm::dvec3& blo, glm::dvec3& bhi) {
          blo = bhi = positions_[tris_[k].p[0]];
          for (int c = 1; c < 3; ++c) {
            blo = glm::min(blo, positions_[tris_[k].p[c]]);
            bhi = glm::max(bhi, positions_[tris_[k].p[c]]);
          }
        },
        [&](std::uint32_t a, std::uint32_t n, const std::uint32_t* perm) {
          std::array<Tri, kSahRange> t;
          std::array<std::uint32_t, kSahRange> m{};
          for (std::uint32_t k = 0; k < n; ++k) {
            t[k] = tris_[a + perm[k]];
            m[k] = src_[a + perm[k]];
          }
          std::copy(t.begin(), t.begin() + n, tris_.begin() + a);
          std::copy(m.begin(), m.begin() + n, src_.begin() + a);
        });
    chunk_first_.push_back(static_cast<std::uint32_t>(nt));
    chunk_tree_.shrink_to_fit();
    chunk_first_.shrink_to_fit();
  }
  // Solids: the unbounded ones (the half-space under a ground) apart, the others in Morton order
  // of their centres under a BVH of their own.
  std::vector<Mesh::Box> bounded;
  for (const Mesh::Box& b : mesh.solids) {
    const bool finite = std::isfinite(b.lo.x) && std::isfinite(b.lo.y) && std::isfinite(b.lo.z) && std::isfinite(b.hi.x) &&
                        std::isfinite(b.hi.y) && std::isfinite(b.hi.z);
    (finite ? bounded : open_solids_).push_back(b);
  }
  if (!bounded.empty()) {
    glm::dvec3 slo = bounded[0].lo, shi = bounded[0].hi;
    for (const Mesh::Box& b : bounded) {
      slo = glm::min(slo, b.lo);
      shi = glm::max(shi, b.hi);
    }
    const glm::dvec3 sext = glm::max(shi - slo, glm::dvec3(1e-300));
    std::vector<std::pair<std::uint32_t, std::uint32_t>> sorder(bounded.size());
    for (std::size_t k = 0; k < bounded.size(); ++k)
      sorder[k] = {morton_code(0.5 * (bounded[k].lo + bounded[k].hi), slo, sext), static_cast<std::uint32_t>(k)};
    std::sort(sorder.begin(), sorder.end());
    solids_.reserve(bounded.size());
    solid_tree_.reserve(2 * bounded.size() - 1);
    std::vector<std::uint32_t> solid_code;
    for (const auto& [c, k] : sorder) {
      solids_.push_back(bounded[k]);
      solid_code.push_back(c);
    }
    mesh_bvh_build(solid_tree_, solid_code.data(), 0, static_cast<std::uint32_t>(solids_.size()),
                   [&](std::uint32_t i, glm::dvec3& blo, glm::dvec3& bhi) {
                     blo = solids_[i].lo;
                     bhi = solids_[i].hi;
                   });
  }
}

// Along any ray from outside the solids a front face comes first (Mesh::solids), so back faces can
// be skipped when the part of every pixel's ray that is cut away (up to the near plane) lies
// outside the solids too: no solid comes within the distance of the near plane's farthest corner.
// The 2^-20 covers the rounding of that distance. O(unbounded solids + log bounded ones) for a
// camera among solids that do not overlap much: their BVH is walked only where a node's box comes
// within reach (a node's distance is at most its solids').
bool MeshScene::skips_back_faces(const Camera& cam, const ViewParams& p) const {
  if (!occlusion_culling_ || (solids_.empty() && open_solids_.empty())) return false;
  const double ax = std::max(cam.cx, cam.width - cam.cx) / cam.focal_px;
  const double ay = std::max(cam.cy, cam.height - cam.cy) / cam.focal_px;
  const double reach = p.near_m * std::sqrt(1.0 + ax * ax + ay * ay) * (1.0 + 0x1p-20);
  const double r2 = reach * reach;
  // Whether box [lo, hi] stays beyond reach; its distance is 0 inside it, also for infinite
  // bounds (the camera is finite).
  const auto beyond = [&](const glm::dvec3& lo, const glm::dvec3& hi) {
    const glm::dvec3 d = glm::max(glm::max(lo - cam.pos_m, cam.pos_m - hi), glm::dvec3(0.0));
    return glm::dot(d, d) > r2;
  };
  for (const Mesh::Box& b : open_solids_)
    if (!beyond(b.lo, b.hi)) return false;
  if (solid_tree_.empty()) return true;
  thread_local std::vector<std::uint32_t> stack;
  stack.assign(1, 0);
  while (!stack.empty()) {
    const Node& nd = solid_tree_[stack.back()];
    const std::uint32_t ni = stack.back();
    stack.pop_back();
    if (beyond(glm::dvec3(nd.lo), glm::dvec3(nd.hi))) continue;
    if (nd.right == 0) {  // a leaf: its solid's own bounds decide
      if (!beyond(solids_[nd.item].lo, solids_[nd.item].hi)) return false;
      continue;
    }
    stack.push_back(ni + 1);
    stack.push_back(nd.right);
  }
  return true;
}

MeshScene::RenderStats MeshScene::last_render_stats() { return scratch().stats; }

std::size_t MeshScene::memory_bytes() const {
  std::size_t n = sizeof(*this) + tris_.capacity() * sizeof(Tri) + positions_.capacity() * sizeof(glm::dvec3) +
                  uvs_.capacity() * sizeof(glm::dvec2) +
                  (chunk_tree_.capacity() + solid_tree_.capacity()) * sizeof(Node) +
                  (chunk_first_.capacity() + src_.capacity()) * sizeof(std::uint32_t) +
                  (solids_.capacity() + open_solids_.capacity()) * sizeof(Mesh::Box) +
                  load_warnings_.capacity() * sizeof(std::string);
  for (const std::string& w : load_warnings_) n += w.capacity();
  return n;
}

void MeshScene::render(const Camera& cam, const ViewParams& p, ViewBuffer& out) const {
  detail::begin_frame(cam, p, out);
  render_impl(cam, p, &out, nullptr);
}

void MeshScene::render_spans(const Camera& cam, const ViewParams& p, SpanBuffer& out) const {
  validate_view_params(p);
  const int levels = mip_level_count(extent_);
  // The per-sample buffer is wanted anyway, or the level cuts are not trustworthy: derive the
  // spans from render()'s samples.
  if (out.keep_samples || !detail::level_cuts(detail::lod_rule(p).bias, levels).ok) {
    IScene::render_spans(cam, p, out);
    return;
  }
  if (out.block_shift < 0 || out.block_shift > 62) throw std::invalid_argument("spans: block_shift must be in [0, 62]");
  out.width = buffer_extent(cam.width, p.divisor);
  out.height = buffer_extent(cam.height, p.divisor);
  out.divisor = p.divisor;
  out.levels = levels;
  out.spans.clear();
  out.has_samples = false;
  out.view.samples.clear();
  out.scene = this;
  out.cam = cam;
  out.params = p;
  render_impl(cam, p, nullptr, &out);
}

void MeshScene::render_impl(const Camera& cam, const ViewParams& p, ViewBuffer* view, SpanBuffer* spans) const {
  const int bw = spans ? spans->width : view->width, bh = spans ? spans->height : view->height;
  Scratch& s = scratch();
  s.begin(cam, p.divisor, bw, bh, tris_.size());
  s.stats.chunks = static_cast<std::uint32_t>(chunk_first_.size() - 1);
  const DepthPass dp(cam, p, s, occlusion_culling_, skips_back_faces(cam, p), src_.data());
  const auto draw = [&](std::uint32_t k) {
    TriGeom g;
    tri_corners(positions_[tris_[k].p[0]], positions_[tris_[k].p[1]], positions_[tris_[k].p[2]], g);
    dp.draw(g.p, g.n, k);
  };
  if (!occlusion_culling_) {
    // The reference: every chunk in the frustum, in index order, every triangle.
    for (const Node& nd : chunk_tree_) {  // preorder: the leaves in chunk order
      if (nd.right != 0 || !dp.in_frustum(glm::dvec3(nd.lo), glm::dvec3(nd.hi))) continue;
      ++s.stats.chunks_in_frustum;
      for (std::uint32_t k = chunk_first_[nd.item]; k < chunk_first_[nd.item + 1]; ++k) draw(k);
    }
    resolve(cam, p, view, spans);
    return;
  }
  // Warm start: last frame's visible triangles first (this thread's previous render of a scene
  // of this size — a hint only: any triangle may be drawn in any order, the tie rule makes the
  // buffer the same). At 60 Hz they cover nearly the same samples again, so the depth is close
  // to final before the hierarchy is walked and most of it fails the occlusion test at once.
  std::vector<std::uint32_t>& hint = s.hint;
  std::sort(hint.begin(), hint.end());
  for (const std::uint32_t k : hint) draw(k);
  // The BVH nearest first: a min-queue of nodes by the least view depth of their boxes, a node
  // taken out tested against the depth drawn so far (a box wholly beyond near and behind it
  // hides everything under it). A child's box lies within its parent's, so its least depth is no
  // less: chunks come out in the order of their least depth, as a sort of all of them would give.
  // `queue` is not a Scratch member: a member added there moved the stats, and raster_poly's
  // register allocation changed with their offsets (+20 % of its profile).
  thread_local std::vector<std::pair<double, std::uint32_t>> queue;
  queue.clear();
  const auto later = [](const std::pair<double, std::uint32_t>& x, const std::pair<double, std::uint32_t>& y) { return x > y; };
  const auto push = [&](std::uint32_t ni) {
    const Node& nd = chunk_tree_[ni];
    const glm::dvec3 lo(nd.lo), hi(nd.hi);
    if (!dp.in_frustum(lo, hi)) return;
    double z = dp.least_depth(lo, hi);
    if (std::isnan(z)) z = -std::numeric_limits<double>::infinity();  // NaN (a box beyond float's range): first, never culled
    queue.emplace_back(z, ni);
    std::push_heap(queue.begin(), queue.end(), later);
  };
  push(0);
  while (!queue.empty()) {
    std::pop_heap(queue.begin(), queue.end(), later);
    const auto [zmin, ni] = queue.back();
    queue.pop_back();
    ++s.stats.nodes_visited;
    const Node& nd = chunk_tree_[ni];
    const bool leaf = nd.right == 0;
    if (leaf) ++s.stats.chunks_in_frustum;
    if (zmin > p.near_m && dp.occluded(glm::dvec3(nd.lo), glm::dvec3(nd.hi), zmin)) {
      if (leaf) ++s.stats.chunks_occluded;
      continue;
    }
    if (!leaf) {
      push(ni + 1);
      push(nd.right);
      continue;
    }
    // The chunk's triangles but those the warm start drew (hint is sorted).
    const std::uint32_t first = chunk_first_[nd.item], end = chunk_first_[nd.item + 1];
    auto h = std::lower_bound(hint.begin(), hint.end(), first);
    for (std::uint32_t k = first; k < end; ++k) {
      if (h != hint.end() && *h == k) {
        ++h;
        continue;
      }
      draw(k);
    }
  }
  resolve(cam, p, view, spans);
}

void MeshScene::resolve(const Camera& cam, const ViewParams& p, ViewBuffer* view, SpanBuffer* spans) const {
  // Classify every buffer pixel and shade the visible front faces exactly. The ray of
  // full-resolution pixel (px, py) is d = D0 + px·ddx + py·ddy (Camera::ray_dir); on a triangle's
  // plane everything a sample needs is a ratio of functions affine in (px, py), so each triangle
  // that owns a sample gets its coefficients once per frame and a sample costs one division:
  //   d·n = a0 + a1·px + a2·py,  ray parameter t = −((o − p0)·n) / (d·n),
  //   texel u = tu0 + gu·(o − p0) + t·(gu·d)   (the hit point is o + t·d; gu·d is affine too),
  //   dT/dx (Igehy's ray differential, lod.h): t·(gu·ddx − (ddx·n)(gu·d)/(d·n)), likewise v, y.
  // Algebraically the ray-plane intersection and plane_footprint_lod; the rounding differs by ulps.
  Scratch& s = scratch();
  const bool to_spans = spans != nullptr;
  const LodRule rule = detail::lod_rule(p);
  const int bw = s.bw, bh = s.bh;
  const double far_iz = 1.0 / p.far_m;
  const double W = static_cast<double>(extent_.width), H = static_cast<double>(extent_.height);
  s.clear_slots();  // `hint` becomes this frame's visible triangles, for the next frame's warm start
  ViewCounters c;
  [[maybe_unused]] MeshSpanOut so{to_spans ? &spans->spans : nullptr, c,
                                  to_spans ? &detail::level_cuts(rule.bias, spans->levels) : nullptr, to_spans ? spans->levels : 1,
                                  to_spans ? spans->block_shift : 0, static_cast<double>(extent_.width),
                                  static_cast<double>(extent_.height)};
  for (int y = 0; y < bh; ++y) {
    const double py = s.sy[static_cast<std::size_t>(y)];
    const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(bw);
    if (to_spans) so.open = false;  // spans stay in a row
    for (int x = 0; x < bw;) {
      const std::size_t idx = row + static_cast<std::size_t>(x);
      const std::uint32_t id = s.id[idx];
      if (id == kNoTri || (id & kBackBit) || tris_[id].t[0] < 0) {
        if (id == kNoTri) {
          if (s.near_cut[idx]) ++c.clipped;
          else ++c.sky;
        } else {
          s.slot_of(id & ~kBackBit);
          if (s.invz[idx] < far_iz) ++c.clipped;
          else if (id & kBackBit) ++c.backfacing;
          else ++c.untextured;
        }
        if (to_spans) so.open = false;
        ++x;
        continue;
      }
      const std::uint32_t slot = s.slot_of(id);
      Shade& h = s.shade[slot];
      if (!s.shaded[slot]) {
        s.shaded[slot] = 1;
        shade_of(tri_geom(tris_[id], positions_, uvs_, W, H), cam, h);
      }
      // The run of this row's samples the same front face owns, four lanes at a time.
      int xe = x + 1;
      while (xe < bw && s.id[row + static_cast<std::size_t>(xe)] == id) ++xe;
      const ShadeRow k = shade_row(h, py, rule, far_iz, extent_);
      ++s.stats.resolve_runs;
      s.stats.resolve_samples += static_cast<std::uint64_t>(xe - x);
      if (to_spans)
        span_run(k, s.sx.data() + x, s.invz.data() + idx, xe - x, static_cast<std::uint32_t>(idx), rule.anisotropic, so);
      else
        append_run_samples(k, s.sx.data() + x, s.invz.data() + idx, xe - x, idx, rule.anisotropic, s.batch, view->samples, c);
      x = xe;
    }
  }
  s.stats.visible_triangles = static_cast<std::uint32_t>(s.hint.size());
  if (to_spans) {
    spans->counters = c;
    spans->samples = so.n_samples;
    // render_pixels shades a span's pixels again from their faces; the swap keeps both buffers'
    // storage (no allocation after warm-up).
    spans->surface = s.id;
  } else {
    view->counters = c;
  }
}

void MeshScene::render_pixels(const SpanBuffer& sb, std::uint32_t pixel, std::uint32_t count,
                              std::vector<ViewSample>& out) const {
  const std::uint32_t bw = static_cast<std::uint32_t>(sb.width);
  if (bw == 0 || pixel / bw >= static_cast<std::uint32_t>(sb.height) || pixel % bw + count > bw)
    throw std::invalid_argument("render_pixels: the pixels are not within one buffer row");
  if (sb.surface.size() != static_cast<std::size_t>(bw) * static_cast<std::size_t>(sb.height))
    throw std::logic_error("render_pixels: the span buffer holds no faces of a mesh render");
  const Camera& cam = sb.cam;
  const ViewParams& p = sb.params;
  const LodRule rule = detail::lod_rule(p);
  const double far_iz = 1.0 / p.far_m;
  const int y = static_cast<int>(pixel / bw), x0 = static_cast<int>(pixel % bw);
  const double py = sample_pos(y, p.divisor, cam.height);
  thread_local std::vector<double> px, iz;
  thread_local ShadeBatch batch;
  // A span's pixels are samples, so none was clipped: 1/z = +inf passes the far test.
  px.resize(static_cast<std::size_t>(count) + 4);
  iz.assign(static_cast<std::size_t>(count) + 4, INFINITY);
  for (std::uint32_t i = 0; i < count + 4; ++i)
    px[i] = sample_pos(x0 + static_cast<int>(std::min(i, count - 1)), p.divisor, cam.width);
  for (std::uint32_t a = 0; a < count;) {
    const std::uint32_t id = sb.surface[pixel + a];
    std::uint32_t e = a + 1;
    while (e < count && sb.surface[pixel + e] == id) ++e;
    if (id == kNoTri || (id & kBackBit) || id >= tris_.size() || tris_[id].t[0] < 0)
      throw std::logic_error("render_pixels: a pixel of the span is not a sample");
    Shade h;
    shade_of(tri_geom(tris_[id], positions_, uvs_, static_cast<double>(extent_.width), static_cast<double>(extent_.height)), cam, h);
    const ShadeRow k = shade_row(h, py, rule, far_iz, extent_);
    for (std::uint32_t b = a; b < e; b += kShadeBatch) {
      const int n = static_cast<int>(std::min<std::uint32_t>(kShadeBatch, e - b));
      shade_batch(k, px.data() + b, iz.data() + b, n, rule.anisotropic, batch);
      for (int j = 0; j < n; ++j) {
        if (batch.cls[j] != kSample) throw std::logic_error("render_pixels: a pixel of the span is not a sample");
        out.push_back(ViewSample{batch.u[j], batch.v[j], batch.lod[j], pixel + b + static_cast<std::uint32_t>(j)});
      }
    }
    a = e;
  }
}

}  // namespace vtsim
