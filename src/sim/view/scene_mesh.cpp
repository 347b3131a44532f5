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

namespace vtsim {

namespace {

constexpr std::uint32_t kNoTri = 0xffffffffu;
constexpr std::uint32_t kBackBit = 0x80000000u;
// Triangles per culling box at most: the town replay ran fastest at 16 (8 the same, 64 15 %
// slower). The chunks are the leaves of the BVH (MeshScene::Node).
constexpr std::uint32_t kChunkSize = 16;
// Morton ranges of at most this many triangles are split by the surface area heuristic instead
// of the Morton grid (chunk_bvh_build): a grid cell's edge falls anywhere in a building, the
// heuristic puts the cut in the street. Four chunks' worth: its sorts stay short.
constexpr std::uint32_t kSahRange = 64;
// The part of a triangle between view depth near/1024 and near is rasterised only to tell
// "clipped" from "sky" in the counters; nearer than that it is ignored (projection blows up).
constexpr double kNearFlagFraction = 1.0 / 1024.0;
// Relative margin of the occlusion test: a triangle's rasterised 1/z exceeds the exact bound of
// its chunk's box only by rounding (a few ulps, far more for a sliver whose plane equation
// cancels); 2^-20 leaves 2^32 ulps.
constexpr double kOccludeMargin = 0x1p-20;
// Ray-box tests one box's occlusion test may make before it calls the box visible: a far box's
// rectangle holds a few dozen samples at divisor 8, and a box whose rays miss that many is rare.
constexpr int kMaxReachTests = 64;

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

// Camera-space vertex: x right, y up, z view depth.
struct CV {
  double x, y, z;
};
// Projected vertex: full-resolution pixel position and 1/z.
struct PV {
  double X, Y, iz;
};

bool lex_less(const CV& a, const CV& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

// Point of segment ab at depth zc, computed from the endpoints in a canonical order so that two
// triangles sharing the edge get bit-identical points (no cracks along clipped shared edges).
CV clip_point(CV a, CV b, double zc) {
  if (lex_less(b, a)) std::swap(a, b);
  const double t = (zc - a.z) / (b.z - a.z);
  return CV{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), zc};
}

// Sutherland–Hodgman against one depth plane: keep z >= zc (keep_above) or z < zc.
int clip_poly(const CV* in, int n, double zc, bool keep_above, CV* out) {
  int m = 0;
  for (int k = 0; k < n; ++k) {
    const CV& a = in[k];
    const CV& b = in[(k + 1) % n];
    const bool ain = keep_above ? a.z >= zc : a.z < zc;
    const bool bin = keep_above ? b.z >= zc : b.z < zc;
    if (ain) out[m++] = a;
    if (ain != bin) out[m++] = clip_point(a, b, zc);
  }
  return m;
}

// Edge equation E(s) = A·sx + (B·sy + C) of edge p→q, positive on its left in pixel coordinates
// (y down). Built from the lexicographically smaller endpoint and negated when the edge runs the
// other way, so the neighbour triangle that walks q→p gets exactly −E at every sample: no sample
// on a shared edge is lost or drawn twice (with the ownership rule below).
struct Edge {
  double A, B, C;
  bool own;  // samples with E == 0 belong to this triangle
};
inline Edge make_edge(const PV& p, const PV& q) {
  const bool swap = q.X < p.X || (q.X == p.X && q.Y < p.Y);
  const PV& a = swap ? q : p;
  const PV& b = swap ? p : q;
  Edge e;
  e.A = -(b.Y - a.Y);
  e.B = b.X - a.X;
  e.C = -(e.A * a.X + e.B * a.Y);
  if (swap) {
    e.A = -e.A;
    e.B = -e.B;
    e.C = -e.C;
  }
  // Ownership (top-left style): the two triangles sharing an edge walk it in opposite directions.
  const double dy = q.Y - p.Y, dx = q.X - p.X;
  e.own = dy > 0.0 || (dy == 0.0 && dx < 0.0);
  return e;
}

// Hierarchical depth: the buffer in tiles of kTile × kTile samples, each with the least 1/z of
// its samples (the farthest surface; 0 while any sample is empty), recomputed lazily when a write
// made it stale. A surface nearer than nothing in a tile cannot win any of its samples.
constexpr int kTileShift = 3;
constexpr int kTile = 1 << kTileShift;

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

struct Scratch {
  std::vector<double> invz;          // 1/view depth of the nearest surface, 0 = none
  std::vector<std::uint32_t> id;     // triangle index | kBackBit, or kNoTri
  std::vector<std::uint8_t> near_cut;  // covered only by geometry the near plane cut away
  std::vector<double> sx, sy;        // sample positions of buffer columns / rows, full-res pixels
                                     // (sx padded by 4 for shade_batch's last lanes)
  ShadeBatch batch;
  std::vector<double> tile_min;      // least invz of the tile's samples, valid unless stale
  std::vector<std::uint8_t> tile_stale;
  int bw = 0, bh = 0, tw = 0;        // buffer size, samples; tiles per row
  // The triangles owning a sample in the last render (< hint_tris): the resolve appends them
  // in the order met, the next render's warm start sorts them (drawn chunks skip them by binary
  // search). A hash table (open addressing, linear probing; kNoTri = empty) maps each to its slot
  // in `hint` and `shade`, its resolve coefficients, computed once a frame where `shaded`: all
  // sized by the buffer (a triangle owns at least one sample) or the mesh, whichever is smaller.
  std::vector<std::uint32_t> hint;
  std::size_t hint_tris = 0;         // triangle count of the mesh the hint is of
  std::vector<Shade> shade;          // per slot
  std::vector<std::uint8_t> shaded;  // per slot
  std::vector<std::uint32_t> slot_key, slot_val;  // the table: triangle -> slot
  std::vector<std::uint32_t> slot_used;           // its filled positions, to empty it
  int slot_shift = 32;               // 32 − log2(table size)
  std::uint64_t frame = 0;           // renders by this thread
  MeshScene::RenderStats stats;      // of the render under way, then the last one

  // Starts a render of a mesh of `tris` triangles into a buf_w × buf_h buffer at divisor `div`:
  // nothing drawn, stats zeroed, the sample positions of this camera, the slot table sized (a mesh
  // of another size drops the warm start). Returns the render's number.
  std::uint64_t begin(const Camera& cam, int div, int buf_w, int buf_h, std::size_t tris) {
    const std::size_t npix = static_cast<std::size_t>(buf_w) * static_cast<std::size_t>(buf_h);
    stats = MeshScene::RenderStats{};
    invz.assign(npix + 4, 0.0);  // + 4: shade_batch reads whole lanes
    id.assign(npix, kNoTri);
    near_cut.assign(npix, 0);
    bw = buf_w;
    bh = buf_h;
    tw = (bw + kTile - 1) >> kTileShift;
    const std::size_t ntiles = static_cast<std::size_t>(tw) * static_cast<std::size_t>((bh + kTile - 1) >> kTileShift);
    tile_min.assign(ntiles, 0.0);
    tile_stale.assign(ntiles, 0);
    sx.resize(static_cast<std::size_t>(bw) + 4);
    sy.resize(static_cast<std::size_t>(bh));
    for (int x = 0; x < bw; ++x) sx[static_cast<std::size_t>(x)] = sample_pos(x, div, cam.width);
    for (int x = bw; x < bw + 4; ++x) sx[static_cast<std::size_t>(x)] = sx[static_cast<std::size_t>(bw - 1)];
    for (int y = 0; y < bh; ++y) sy[static_cast<std::size_t>(y)] = sample_pos(y, div, cam.height);
    if (hint_tris != tris) {
      hint_tris = tris;
      hint.clear();
    }
    // Table size: a power of two >= 2 · min(samples, triangles), the most a render can see (at
    // most half full: short probes).
    std::size_t cap = 64;
    while (cap < 2 * std::min(npix, tris)) cap *= 2;
    if (slot_key.size() < cap) {
      slot_key.assign(cap, kNoTri);
      slot_val.resize(cap);
      slot_used.clear();
      slot_shift = 32 - std::countr_zero(cap);
    }
    return ++frame;
  }

  // Empties the table and the slots (the resolve of a new frame).
  void clear_slots() {
    for (const std::uint32_t i : slot_used) slot_key[i] = kNoTri;
    slot_used.clear();
    hint.clear();
    shade.clear();
    shaded.clear();
  }

  // The slot of triangle k, made on first sight (appending k to `hint`).
  std::uint32_t slot_of(std::uint32_t k) {
    // Fibonacci hashing (Knuth, TAOCP vol. 3, 6.4): the high bits of k · 2^32/φ.
    const std::uint32_t mask = static_cast<std::uint32_t>(slot_key.size() - 1);
    std::uint32_t i = (k * 0x9e3779b9u) >> slot_shift;
    while (true) {
      if (slot_key[i] == k) return slot_val[i];
      if (slot_key[i] == kNoTri) break;
      i = (i + 1) & mask;
    }
    const auto slot = static_cast<std::uint32_t>(hint.size());
    slot_key[i] = k;
    slot_val[i] = slot;
    slot_used.push_back(i);
    hint.push_back(k);
    shade.emplace_back();
    shaded.push_back(0);
    return slot;
  }

  double tile_least(int tx, int ty) {
    const std::size_t t = static_cast<std::size_t>(ty) * static_cast<std::size_t>(tw) + static_cast<std::size_t>(tx);
    if (tile_stale[t]) {
      double m = INFINITY;
      const int x0 = tx << kTileShift, x1 = std::min(bw, x0 + kTile);
      const int y0 = ty << kTileShift, y1 = std::min(bh, y0 + kTile);
      for (int y = y0; y < y1; ++y) {
        const double* row = invz.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(bw);
        for (int x = x0; x < x1; ++x) m = std::min(m, row[x]);
      }
      tile_min[t] = m;
      tile_stale[t] = 0;
    }
    return tile_min[t];
  }

  // Columns [x0, x1] of row y were written: their tiles' least 1/z is recomputed when next asked.
  void mark_stale(int y, int x0, int x1) {
    std::uint8_t* row = tile_stale.data() + static_cast<std::size_t>(y >> kTileShift) * static_cast<std::size_t>(tw);
    for (int t = x0 >> kTileShift; t <= x1 >> kTileShift; ++t) row[t] = 1;
  }

  // True when every sample in columns [x0, x1] × rows [y0, y1] holds a surface with 1/z > bound
  // (also when the range is empty): tiles first, the samples of a tile only where its least 1/z
  // does not decide.
  bool all_nearer(int x0, int x1, int y0, int y1, double bound) {
    return all_nearer_where(x0, x1, y0, y1, bound, [](int, int) { return true; });
  }

  // all_nearer, where a sample that is not nearer counts only if `reaches(x, y)` (a superset test:
  // may the tested box cover that sample?). After kMaxReachTests such tests it gives up (false).
  template <class Reaches>
  bool all_nearer_where(int x0, int x1, int y0, int y1, double bound, const Reaches& reaches) {
    int tests = 0;
    for (int ty = y0 >> kTileShift; ty <= y1 >> kTileShift; ++ty)
      for (int tx = x0 >> kTileShift; tx <= x1 >> kTileShift; ++tx) {
        if (tile_least(tx, ty) > bound) continue;
        const int xa = std::max(x0, tx << kTileShift), xb = std::min(x1, (tx << kTileShift) + kTile - 1);
        const int ya = std::max(y0, ty << kTileShift), yb = std::min(y1, (ty << kTileShift) + kTile - 1);
        for (int y = ya; y <= yb; ++y) {
          const double* row = invz.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(bw);
          for (int x = xa; x <= xb; ++x)
            if (!(row[x] > bound) && (++tests > kMaxReachTests || reaches(x, y))) return false;
        }
      }
    return true;
  }
};

// The render scratch of this thread (reused: no allocation after warm-up).
Scratch& scratch() {
  thread_local Scratch s;
  return s;
}

// Buffer columns whose sample position may lie in [lo, hi] (a superset; the edge test decides).
// Called per rasterised row, so inlined, with 1/div hoisted by the caller's loop and floor/ceil
// by conversion (the x86-64 baseline has no roundsd: std::floor is a libm call). The reciprocal's
// rounding moves a quotient by an ulp, far inside the one-column margin on each side.
[[gnu::always_inline]] inline void sample_range(double lo, double hi, int div, int n, int& b0, int& b1) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) {
    b0 = 0;
    b1 = -1;
    return;
  }
  const double off = static_cast<double>(div / 2) + 0.5, inv = 1.0 / static_cast<double>(div);
  const double lim = static_cast<double>(n) + 4.0;  // clamped first: the conversions stay exact
  const double ta = std::clamp((lo - off) * inv, -4.0, lim), tb = std::clamp((hi - off) * inv, -4.0, lim);
  int a = static_cast<int>(ta), b = static_cast<int>(tb);  // toward zero, then to floor / ceil
  a -= static_cast<double>(a) > ta;
  b += static_cast<double>(b) < tb;
  b0 = std::clamp(a - 1, 0, n - 1);
  b1 = std::clamp(b + 1, -1, n - 1);
}

// Rasterises a convex polygon (fan) at the buffer's samples. Depth mode: nearest 1/z wins and
// writes `tag`; flag mode (depth == false): marks near_cut only. Every quantity at a sample is
// evaluated from the sample's own position (no incremental stepping), so coverage and depth at a
// full-resolution pixel do not depend on the divisor.
void raster_poly(const PV* v, int n, std::uint32_t tag, bool depth, int div, int bw, int bh, const std::uint32_t* src, Scratch& s) {
  for (int k = 1; k + 1 < n; ++k) {
    PV a = v[0], b = v[k], c = v[k + 1];
    double area = (b.X - a.X) * (c.Y - a.Y) - (b.Y - a.Y) * (c.X - a.X);
    if (!(area != 0.0) || !std::isfinite(area)) continue;
    // Orient so that the inside is where all three edge functions are positive.
    if (area < 0.0) std::swap(b, c);
    int x0, x1, y0, y1;
    sample_range(std::min({a.X, b.X, c.X}), std::max({a.X, b.X, c.X}), div, bw, x0, x1);
    if (x0 > x1) continue;
    sample_range(std::min({a.Y, b.Y, c.Y}), std::max({a.Y, b.Y, c.Y}), div, bh, y0, y1);
    if (y0 > y1) continue;
    const Edge e0 = make_edge(a, b), e1 = make_edge(b, c), e2 = make_edge(c, a);
    // 1/z is affine in the pixel position: iz = (E_bc·iz_a + E_ca·iz_b + E_ab·iz_c) / (2·area).
    const double sum = e1.A * a.X + e1.B * a.Y + e1.C;  // E_bc at a = twice the area
    if (!(sum > 0.0)) continue;
    const double inv = 1.0 / sum;
    const double P = (e1.A * a.iz + e2.A * b.iz + e0.A * c.iz) * inv;
    const double Q = (e1.B * a.iz + e2.B * b.iz + e0.B * c.iz) * inv;
    const double R = (e1.C * a.iz + e2.C * b.iz + e0.C * c.iz) * inv;
    // Per row, the columns between the edges' crossings of the row (each edge bounds x from one
    // side where A != 0): a superset (sample_range's margin) of the covered samples, which the
    // exact test below then decides. Large triangles test ~1/3 of their bounding box this way.
    const double ia0 = e0.A != 0.0 ? -1.0 / e0.A : 0.0, ia1 = e1.A != 0.0 ? -1.0 / e1.A : 0.0,
                 ia2 = e2.A != 0.0 ? -1.0 / e2.A : 0.0;
    const double bx0 = std::min({a.X, b.X, c.X}), bx1 = std::max({a.X, b.X, c.X});
    // Sample inside: E > 0 for all three edges, or E == 0 on an edge this triangle owns (NaN: out).
    const auto inside = [&](double f0, double f1, double f2) {
      return (f0 > 0.0 || (f0 == 0.0 && e0.own)) && (f1 > 0.0 || (f1 == 0.0 && e1.own)) &&
             (f2 > 0.0 || (f2 == 0.0 && e2.own));
    };
    // Locals, not members: the scratch is thread_local and byte stores could alias its members.
    const double* const sxp = s.sx.data();
    double* const invz = s.invz.data();
    std::uint32_t* const ids = s.id.data();
    std::uint8_t* const near_cut = s.near_cut.data();
    const std::uint32_t tid = tag & ~kBackBit;
    // Nearest wins; an exact tie (a sample on a silhouette edge, where a back face meets the
    // front face before it; coincident faces) goes to the triangle that comes first in the Mesh
    // (src: its index there), as a GPU drawing the mesh in order with a "less" depth test keeps it. So the chunks may be drawn in any order (nearest first, below), and how the BVH
    // orders the triangles never shows in the buffer.
    const auto depth_write = [&](std::size_t idx, double iz) {
      if (!(iz > invz[idx] ||
            (iz == invz[idx] && ((ids[idx] & ~kBackBit) == (kNoTri & ~kBackBit) || src[tid] < src[ids[idx] & ~kBackBit]))))
        return false;
      invz[idx] = iz;
      ids[idx] = tag;
      return true;
    };
    for (int y = y0; y <= y1; ++y) {
      const double sy = s.sy[static_cast<std::size_t>(y)];
      const double r0 = e0.B * sy + e0.C, r1 = e1.B * sy + e1.C, r2 = e2.B * sy + e2.C, rz = Q * sy + R;
      double lo = bx0, hi = bx1;
      const auto bound = [&](double A, double ia, double r) {
        if (A == 0.0) return;
        const double xc = r * ia;  // E = A·x + r crosses zero here (NaN/inf: no bound)
        if (A > 0.0) {
          if (xc > lo) lo = xc;
        } else if (xc < hi) {
          hi = xc;
        }
      };
      bound(e0.A, ia0, r0);
      bound(e1.A, ia1, r1);
      bound(e2.A, ia2, r2);
      int xa, xb;  // lo > hi by rounding (a vertex on a sample) still gets the margin
      sample_range(lo, hi, div, bw, xa, xb);
      xa = std::max(xa, x0);
      xb = std::min(xb, x1);
      const std::size_t rowi = static_cast<std::size_t>(y) * static_cast<std::size_t>(bw);
      if (depth) {
        ++s.stats.raster_rows;
        s.stats.depth_tests += static_cast<std::uint64_t>(std::max(0, xb - xa + 1));
      }
      if (!depth) {
        for (int x = xa; x <= xb; ++x) {
          const double sx = sxp[x];
          const double f0 = e0.A * sx + r0, f1 = e1.A * sx + r1, f2 = e2.A * sx + r2;
          if (inside(f0, f1, f2)) near_cut[rowi + static_cast<std::size_t>(x)] = 1;
        }
        continue;
      }
      if (std::isfinite(r0) && std::isfinite(r1) && std::isfinite(r2)) {
        // The covered columns of the row are one interval, found from its two ends: along the
        // row each edge's computed E = fl(fl(A·sx) + r) is monotone in sx (rounding is monotone,
        // sample positions increase, r is finite so no inf − inf), so each edge's "inside" test
        // holds on a prefix or a suffix of the columns and all three on an interval. Between its
        // ends no sample needs an edge test — the same samples as testing each one.
        const auto in = [&](int x) {
          const double sx = sxp[x];
          return inside(e0.A * sx + r0, e1.A * sx + r1, e2.A * sx + r2);
        };
        while (xa <= xb && !in(xa)) ++xa;
        while (xb > xa && !in(xb)) --xb;
        bool wrote = false;
        for (int x = xa; x <= xb; ++x) wrote |= depth_write(rowi + static_cast<std::size_t>(x), P * sxp[x] + rz);
        if (wrote) s.mark_stale(y, xa, xb);  // a superset of the tiles written: only lazier
        continue;
      }
      int wx0 = bw, wx1 = -1;  // columns written in this row
      for (int x = xa; x <= xb; ++x) {
        const double sx = sxp[x];
        if (!inside(e0.A * sx + r0, e1.A * sx + r1, e2.A * sx + r2)) continue;
        if (depth_write(rowi + static_cast<std::size_t>(x), P * sx + rz)) {
          wx0 = std::min(wx0, x);
          wx1 = std::max(wx1, x);
        }
      }
      if (wx1 >= 0) s.mark_stale(y, wx0, wx1);
    }
  }
}

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
