#pragma once
// The mesh scene's bounding-volume hierarchy (scene_mesh.h): chunks of triangles in Morton order,
// split on the grid down to kSahRange triangles and by the surface area heuristic below.
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

#include "sim/view/scene_mesh.h"

namespace vtsim {

namespace {

// Triangles per culling box at most: the town replay ran fastest at 16 (8 the same, 64 15 %
// slower). The chunks are the leaves of the BVH (MeshScene::Node).
constexpr std::uint32_t kChunkSize = 16;
// Morton ranges of at most this many triangles are split by the surface area heuristic instead
// of the Morton grid (chunk_bvh_build): a grid cell's edge falls anywhere in a building, the
// heuristic puts the cut in the street. Four chunks' worth: its sorts stay short.
constexpr std::uint32_t kSahRange = 64;

std::uint32_t spread_bits10(std::uint32_t x) {  // 10 bits -> every third bit (Morton)
  x &= 0x3ffu;
  x = (x | (x << 16)) & 0x030000ffu;
  x = (x | (x << 8)) & 0x0300f00fu;
  x = (x | (x << 4)) & 0x030c30c3u;
  x = (x | (x << 2)) & 0x09249249u;
  return x;
}

// Morton code of point c in box [lo, lo + ext], 10 bits an axis.
std::uint32_t morton_code(const glm::dvec3& c, const glm::dvec3& lo, const glm::dvec3& ext) {
  const glm::dvec3 q = glm::clamp((c - lo) / ext, 0.0, 1.0) * 1023.0;
  return spread_bits10(static_cast<std::uint32_t>(q.x)) | (spread_bits10(static_cast<std::uint32_t>(q.y)) << 1) |
         (spread_bits10(static_cast<std::uint32_t>(q.z)) << 2);
}

void set_box_outward(glm::vec3& flo, glm::vec3& fhi, const glm::dvec3& lo, const glm::dvec3& hi) {
  for (int c = 0; c < 3; ++c) {  // to float, outward
    float l = static_cast<float>(lo[c]), h = static_cast<float>(hi[c]);
    if (static_cast<double>(l) > lo[c]) l = std::nextafter(l, -INFINITY);
    if (static_cast<double>(h) < hi[c]) h = std::nextafter(h, INFINITY);
    flo[c] = l;
    fhi[c] = h;
  }
}

float box_area(const glm::vec3& lo, const glm::vec3& hi) {
  const glm::vec3 e = hi - lo;
  return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
}

// Where a Morton range [a, b) (code nondecreasing) splits: where the highest bit in which its
// first and last codes differ turns to 1 (Karras 2012), so each side covers one cell of the grid;
// a range of one code is halved.
std::uint32_t morton_split(const std::uint32_t* code, std::uint32_t a, std::uint32_t b) {
  if (code[a] == code[b - 1]) return a + (b - a) / 2;
  const std::uint32_t bit = std::bit_floor(code[a] ^ code[b - 1]);
  return static_cast<std::uint32_t>(std::partition_point(code + a, code + b, [&](std::uint32_t c) { return (c & bit) == 0; }) - code);
}

// Node `me`'s box: the union of its children's (the left one at me + 1).
template <class Node>
void join_children(std::vector<Node>& nodes, std::size_t me) {
  const Node& l = nodes[me + 1];
  const Node& r = nodes[nodes[me].right];
  nodes[me].lo = glm::min(l.lo, r.lo);
  nodes[me].hi = glm::max(l.hi, r.hi);
}

// Appends the BVH over items [a, b) (box(i) gives item i's lo and hi; code[i] its Morton code,
// nondecreasing) to `nodes` in preorder — an LBVH (Lauterbach et al. 2009): a node splits its
// range at morton_split, so each child covers one cell of the Morton grid and the boxes stay
// compact (halving the range instead joins the ends of two distant cells). Depth at
// most 30 + log2 n. O(n) nodes (2n − 1), O(n log n) time. The solids' hierarchy; the chunks'
// (chunk_bvh_build) is this down to kSahRange triangles and the area heuristic below.
template <class Node, class BoxOf>
void mesh_bvh_build(std::vector<Node>& nodes, const std::uint32_t* code, std::uint32_t a, std::uint32_t b, const BoxOf& box) {
  const std::size_t me = nodes.size();
  nodes.emplace_back();
  if (b - a == 1) {
    glm::dvec3 lo, hi;
    box(a, lo, hi);
    set_box_outward(nodes[me].lo, nodes[me].hi, lo, hi);
    nodes[me].item = a;
    return;
  }
  const std::uint32_t mid = morton_split(code, a, b);
  mesh_bvh_build(nodes, code, a, mid, box);
  nodes[me].right = static_cast<std::uint32_t>(nodes.size());
  mesh_bvh_build(nodes, code, mid, b, box);
  join_children(nodes, me);
}

// A subtree of the chunk tree over at most kSahRange triangles, their bounds loaded once, in
// float rounded outward as the nodes hold them (the heuristic only picks cuts: float suffices).
struct SahRange {
  std::array<glm::vec3, kSahRange> lo, hi;  // triangle j's bounds
  std::array<std::pair<float, std::uint32_t>, kSahRange> key{};  // (2 × centroid, triangle)
  std::array<float, kSahRange> right_area{};
};

// The subtree over triangles perm[0, n) of `r` (positions pos, pos + 1, … in the tree's order):
// cut where the surface area heuristic puts it (MacDonald & Booth 1990: the least
// A_L·n_L + A_R·n_R over the triangles sorted by centroid; perm reordered) until a range holds
// at most kChunkSize, a leaf: chunk first.size() (pushed: its first position).
template <class Node>
void sah_build(std::vector<Node>& nodes, std::vector<std::uint32_t>& first, SahRange& r, std::uint32_t* perm,
               std::uint32_t n, std::uint32_t pos) {
  const std::size_t me = nodes.size();
  nodes.emplace_back();
  if (n <= kChunkSize) {
    glm::vec3 lo = r.lo[perm[0]], hi = r.hi[perm[0]];
    for (std::uint32_t k = 1; k < n; ++k) {
      lo = glm::min(lo, r.lo[perm[k]]);
      hi = glm::max(hi, r.hi[perm[k]]);
    }
    nodes[me].lo = lo;
    nodes[me].hi = hi;
    nodes[me].item = static_cast<std::uint32_t>(first.size());
    first.push_back(pos);
    return;
  }
  // Along the axis where the centroids spread most (all three axes found the town's cuts as well
  // for twice the build time: docs/view.md), the triangles sorted by centroid, ties by triangle
  // (deterministic); the suffixes' box areas, then each cut's cost from the prefix's box.
  glm::vec3 clo = r.lo[perm[0]] + r.hi[perm[0]], chi = clo;  // twice the centroids' bounds
  for (std::uint32_t k = 1; k < n; ++k) {
    clo = glm::min(clo, r.lo[perm[k]] + r.hi[perm[k]]);
    chi = glm::max(chi, r.lo[perm[k]] + r.hi[perm[k]]);
  }
  const glm::vec3 spread = chi - clo;
  const int axis = spread.x >= spread.y && spread.x >= spread.z ? 0 : spread.y >= spread.z ? 1 : 2;
  for (std::uint32_t k = 0; k < n; ++k) r.key[k] = {r.lo[perm[k]][axis] + r.hi[perm[k]][axis], perm[k]};
  std::sort(r.key.begin(), r.key.begin() + n);
  glm::vec3 lo = r.lo[r.key[n - 1].second], hi = r.hi[r.key[n - 1].second];
  for (std::uint32_t k = n - 1; k > 0; --k) {  // right_area[k]: sorted [k, n)
    lo = glm::min(lo, r.lo[r.key[k].second]);
    hi = glm::max(hi, r.hi[r.key[k].second]);
    r.right_area[k] = box_area(lo, hi);
  }
  float best = std::numeric_limits<float>::infinity();
  std::uint32_t cut = 0;
  lo = r.lo[r.key[0].second];
  hi = r.hi[r.key[0].second];
  for (std::uint32_t k = 1; k < n; ++k) {  // the cut before sorted k: the left is [0, k)
    const float cost = box_area(lo, hi) * static_cast<float>(k) + r.right_area[k] * static_cast<float>(n - k);
    if (cost < best) {
      best = cost;
      cut = k;
    }
    lo = glm::min(lo, r.lo[r.key[k].second]);
    hi = glm::max(hi, r.hi[r.key[k].second]);
  }
  if (cut > 0) {
    for (std::uint32_t k = 0; k < n; ++k) perm[k] = r.key[k].second;
  } else {
    cut = n / 2;  // every cost NaN (bounds beyond float's range): halved, in Morton order
  }
  sah_build(nodes, first, r, perm, cut, pos);
  nodes[me].right = static_cast<std::uint32_t>(nodes.size());
  sah_build(nodes, first, r, perm + cut, n - cut, pos + cut);
  join_children(nodes, me);
}

// The chunk tree over the triangles at positions [a, b) (Morton order; code[k] the code at
// position k): split at the Morton grid as mesh_bvh_build does while the range holds more than
// kSahRange triangles, below that by sah_build, whose order of the range's triangles
// reorder(a, n, perm) applies (position a + k then holds the one at a + perm[k]). Morton above
// and the heuristic below, as hybrid builders do (Pantaleoni & Luebke 2010's HLBVH the other way
// round): the grid keeps the build O(n log n), the heuristic keeps a chunk's box from spanning a
// street (such a box holds air that reaches sky samples no depth hides, so it is opened and
// drawn: docs/view.md "Mesh renderer scaling"). tri_box(k, lo, hi) gives the bounds of the
// triangle at position k.
template <class Node, class TriBox, class Reorder>
void chunk_bvh_build(std::vector<Node>& nodes, std::vector<std::uint32_t>& first, const std::uint32_t* code,
                     std::uint32_t a, std::uint32_t b, SahRange& r, const TriBox& tri_box, const Reorder& reorder) {
  const std::uint32_t n = b - a;
  if (n <= kSahRange) {
    std::array<std::uint32_t, kSahRange> perm{};
    glm::dvec3 lo, hi;
    for (std::uint32_t k = 0; k < n; ++k) {
      tri_box(a + k, lo, hi);
      set_box_outward(r.lo[k], r.hi[k], lo, hi);
      perm[k] = k;
    }
    sah_build(nodes, first, r, perm.data(), n, a);
    reorder(a, n, perm.data());
    return;
  }
  const std::size_t me = nodes.size();
  nodes.emplace_back();
  const std::uint32_t mid = morton_split(code, a, b);
  chunk_bvh_build(nodes, first, code, a, mid, r, tri_box, reorder);
  nodes[me].right = static_cast<std::uint32_t>(nodes.size());
  chunk_bvh_build(nodes, first, code, mid, b, r, tri_box, reorder);
  join_children(nodes, me);
}

}  // namespace

}  // namespace vtsim
