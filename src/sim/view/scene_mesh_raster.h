#pragma once
// The mesh scene's rasteriser (scene_mesh.h): near-plane clipping, the per-thread scratch (depth
// buffer, hierarchical depth tiles, warm start) and the polygon rasteriser at the buffer's samples.
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

#include "sim/view/scene_mesh_shade.h"

namespace vtsim {

namespace {

constexpr std::uint32_t kNoTri = 0xffffffffu;
constexpr std::uint32_t kBackBit = 0x80000000u;
// Ray-box tests one box's occlusion test may make before it calls the box visible: a far box's
// rectangle holds a few dozen samples at divisor 8, and a box whose rays miss that many is rare.
constexpr int kMaxReachTests = 64;

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

}  // namespace

}  // namespace vtsim
