#pragma once
// Mesh scene: triangles with unique UVs into one virtual texture, rasterised at the feedback
// buffer's sample positions with a depth buffer (docs/view.md). Visibility comes from the
// rasteriser (near-plane clipping, 1/z depth test, back faces kept as occluders); each visible
// sample is then shaded exactly: its ray meets the triangle's plane, whose affine texel map gives
// the texel and, through ray differentials, dT/dx and dT/dy per full-resolution pixel.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "sim/view/mesh.h"
#include "sim/view/scene.h"

namespace vtsim {

// Render cost O(visible chunks' triangles + covered samples + log n): chunks of at most 16
// triangles are the leaves of a binary bounding-volume hierarchy (Morton order split on the grid,
// an LBVH: Lauterbach et al. 2009, down to 64 triangles; below, by the surface area heuristic so
// that a chunk's box does not span a street), traversed nearest first from a priority queue;
// a node outside the frustum, or whose box lies behind the depth drawn so far, is skipped with
// everything under it (hierarchical occlusion culling: Greene, Kass & Miller 1993, against a
// hierarchical depth buffer of 8×8-sample tiles that answers most tests without reading samples),
// and so is each triangle of a drawn chunk. A frame touches the nodes on the paths to the chunks
// it draws and their occluded or off-frustum siblings: O(drawn chunks · log n) in the worst case,
// O(drawn chunks + log n) when what is drawn is one compact region, independent of the hidden rest.
// Drawing starts with the triangles that owned samples in this thread's previous render (a warm
// start: at 60 Hz they fill nearly the same depth), which never changes the result, only how much
// is culled. The scratch (depth buffer, warm start, per-frame shading) is per thread and sized by
// the buffer, not the mesh (thread_local, reused, so no allocation after warm-up): render is
// thread-safe. Memory: memory_bytes(); construction O(n log n) (the Morton sort). An exact depth
// tie goes to the triangle first in the Mesh, so the hierarchy's order never shows in a render.
// Back faces (seen from behind, per triangle: the camera is behind its plane) are rasterised as
// occluders and never sampled: a camera inside a closed wall sees nothing, as on a solid. When the
// mesh promises solids (Mesh::solids) and none comes within the near plane's reach of the camera,
// no back face can be the nearest surface, and they are skipped (~60 % of the triangles a town
// street view draws).
class MeshScene final : public IScene {
 public:
  // texel = floor(uv · (W, H)) for the texture extent; throws InputError("mesh", ...) for an empty
  // mesh, indices out of range, non-finite data or more than 2^31 − 1 triangles, and
  // InputError("texture", ...) for an extent below 1 or above 2^52 texels a side.
  MeshScene(const Mesh& mesh, TextureExtent extent);
  void surface_at(const Camera& cam, const ViewParams& params, double px, double py, SurfaceHit& hit) const override;
  TextureExtent texture() const override { return extent_; }
  void render(const Camera& cam, const ViewParams& params, ViewBuffer& out) const override;
  // Spans without materialising samples: the same rasterisation, then per row run of a front face
  // the resolve's arithmetic four samples at a time and the open span's test as double
  // comparisons (level cuts instead of the logarithm, span_build.h); only a span's first sample is
  // classified one by one. Keeps the buffer's faces (SpanBuffer::surface) for render_pixels.
  // keep_samples falls back to render() + spans.
  void render_spans(const Camera& cam, const ViewParams& params, SpanBuffer& out) const override;
  void render_pixels(const SpanBuffer& sb, std::uint32_t pixel, std::uint32_t count,
                     std::vector<ViewSample>& out) const override;

  std::size_t triangle_count() const { return tris_.size(); }
  // Bytes this scene holds (the object and its vectors' capacities; not the per-thread scratch).
  std::size_t memory_bytes() const;
  std::vector<std::string> load_warnings() const override { return load_warnings_; }
  void set_load_warnings(std::vector<std::string> w) { load_warnings_ = std::move(w); }
  // What this thread's last render or render_spans of a mesh did: where the culling stopped each
  // triangle and how many samples the rasteriser and the resolve touched (bench_vt prints it per
  // frame; docs/vt.md "Speed"). Counted per chunk, triangle and row, never per sample.
  struct RenderStats {
    std::uint32_t chunks = 0;               // in the mesh
    std::uint32_t chunks_in_frustum = 0;    // reached: in the frustum, under no culled node
    std::uint32_t chunks_occluded = 0;      // of those, skipped by their own occlusion test
    std::uint32_t nodes_visited = 0;        // BVH nodes taken from the traversal's queue
    std::uint32_t triangles_visited = 0;    // reached by the warm start or a drawn chunk
    std::uint32_t back_faces_skipped = 0;   // of those, back faces skipped (skips_back_faces)
    std::uint32_t triangles_occluded = 0;   // skipped by the per-triangle occlusion test
    std::uint32_t triangles_rasterised = 0; // depth-rasterised (near-clipped parts count once)
    std::uint64_t raster_rows = 0;          // rows those triangles spanned
    std::uint64_t depth_tests = 0;          // samples tested against the depth buffer
    std::uint32_t visible_triangles = 0;    // owning a sample after the resolve
    std::uint32_t resolve_runs = 0;         // row runs of one front face shaded
    std::uint64_t resolve_samples = 0;      // samples in those runs
    // Sums the counts of several renders (chunks, the mesh's, stays the larger).
    RenderStats& operator+=(const RenderStats& o) {
      chunks = chunks > o.chunks ? chunks : o.chunks;
      chunks_in_frustum += o.chunks_in_frustum;
      chunks_occluded += o.chunks_occluded;
      nodes_visited += o.nodes_visited;
      triangles_visited += o.triangles_visited;
      back_faces_skipped += o.back_faces_skipped;
      triangles_occluded += o.triangles_occluded;
      triangles_rasterised += o.triangles_rasterised;
      raster_rows += o.raster_rows;
      depth_tests += o.depth_tests;
      visible_triangles += o.visible_triangles;
      resolve_runs += o.resolve_runs;
      resolve_samples += o.resolve_samples;
      return *this;
    }
  };
  static RenderStats last_render_stats();
  // Occlusion culling (on by default): chunks drawn nearest first, those hidden behind what is
  // drawn skipped, and back faces skipped where the solids allow. Off: every chunk in the
  // frustum, in index order, every back face — the reference the tests compare with. Not to be
  // changed while another thread renders.
  void set_occlusion_culling(bool on) { occlusion_culling_ = on; }
  // Whether a render from this camera skips back faces: culling is on, the mesh has solids, and
  // none of them holds the camera or reaches the near plane (then no back face is the nearest
  // surface anywhere, and the buffer is what drawing them gives).
  bool skips_back_faces(const Camera& cam, const ViewParams& params) const;

 private:
  // 24 bytes: the corners and texture coordinates are shared (positions_, uvs_); the normal and
  // the texel map are computed when the triangle is drawn or shaded (scene_mesh.cpp, TriGeom).
  struct Tri {
    std::uint32_t p[3] = {0, 0, 0};  // corners: indices into positions_
    std::int32_t t[3] = {-1, -1, -1};  // texture coordinates: indices into uvs_; −1: untextured
  };
  // A node of a bounding-volume hierarchy in preorder: its left child is the next node, `right`
  // the other one's index; a leaf (right == 0: the root is nobody's child) holds item `item`
  // (chunk `item`: triangles [chunk_first_[item], chunk_first_[item + 1]); or solids_[item]). The box is in
  // float rounded outward: culling with a larger box only culls less (the buffer is the same),
  // and 32 bytes a node halve the walk's cache misses.
  struct Node {
    glm::vec3 lo, hi;     // bounding box, world metres
    std::uint32_t right = 0, item = 0;
  };
  // render (view: the begun per-sample buffer) and render_spans (spans: its fields set but the
  // spans'): the depth pass into this thread's scratch, then resolve.
  void render_impl(const Camera& cam, const ViewParams& p, ViewBuffer* view, SpanBuffer* spans) const;
  // The scratch's depth and faces of the render under way into samples (view) or spans.
  void resolve(const Camera& cam, const ViewParams& p, ViewBuffer* view, SpanBuffer* spans) const;

  TextureExtent extent_;
  std::vector<Tri> tris_;           // in the chunk tree's order (Morton, then by the area heuristic)
  std::vector<std::uint32_t> src_;  // per triangle, its index in the Mesh (the depth test's tie rule)
  std::vector<glm::dvec3> positions_;  // world metres, each bit pattern once
  std::vector<glm::dvec2> uvs_;     // texture coordinates, each bit pattern once
  std::vector<std::string> load_warnings_;
  std::vector<Node> chunk_tree_;    // over the chunks (at most 16 triangles each)
  std::vector<std::uint32_t> chunk_first_;  // chunk i: triangles [chunk_first_[i], chunk_first_[i + 1])
  std::vector<Mesh::Box> solids_;   // the bounded ones, in Morton order of their centres
  std::vector<Node> solid_tree_;    // over solids_ (skips_back_faces: O(log solids) near the camera)
  std::vector<Mesh::Box> open_solids_;  // solids with an infinite bound, tested one by one
  bool occlusion_culling_ = true;
};

}  // namespace vtsim
