#include "sim/view/scene_plane.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "core/error.h"
#include "sim/view/render_util.h"
#include "sim/view/simd.h"
#include "sim/view/span_build.h"

namespace vtsim {

namespace {

using detail::block_bounds;
using detail::cut_level;
using detail::LevelCuts;
using detail::level_cuts;
using detail::span_bounds;
using detail::SpanBounds;

constexpr int kChunk = 64;  // pixels per batch: arrays stay in L1, loops long enough

using simd::v4d;
using simd::load4;
using simd::store4;

// Per-pixel values of one batch of a row; classification and the logarithm follow in a scalar
// pass.
struct Batch {
  alignas(32) double dz[kChunk];
  alignas(32) double t[kChunk];
  alignas(32) double tu[kChunk];  // continuous level-0 texel coordinates of the hit
  alignas(32) double tv[kChunk];
  alignas(32) double q[kChunk];   // squared footprint for the LOD rule, clamped
};

// Row constants of the arithmetic.
struct RowConsts {
  double rx, ry, rz, Lx, Ly, Lz, Ux, Uy, Uz, ox, oy, oz, tpm, tpm2, inv_a2;
};

struct Lanes {
  v4d dz, t, tu, tv, q;
};

// Row values that do not depend on the column when the camera has no roll (L.z = 0): then
// d.z = r.z + a·L.z is r.z exactly for every column (a·0 = ±0, and r.z != 0 is required), and so
// are 1/d.z, t, the footprint factors and s; and kx = L.z/d.z = ±0 makes ax = kx·dx − L.x = −L.x
// (or ±0 when L.x = 0) for every finite dx, so ax² + ay² and lx2 are the same bits in every
// column too. Hoisting them leaves every lane's value unchanged.
struct RowFlat {
  double dz, r, t, kx, ky, s, lx2;
};
inline RowFlat row_flat(const RowConsts& k, double a0) {
  RowFlat f;
  f.dz = k.rz;
  f.r = 1.0 / f.dz;
  f.t = -k.oz * f.r;
  f.kx = k.Lz * f.r;
  f.ky = k.Uz * f.r;
  f.s = f.t * f.t * k.tpm2;
  const double dx = k.rx + a0 * k.Lx, dy = k.ry + a0 * k.Ly;
  const double ax = f.kx * dx - k.Lx, ay = f.kx * dy - k.Ly;
  f.lx2 = f.s * (ax * ax + ay * ay);
  return f;
}

// The per-pixel arithmetic of four columns a (branch-free); kFlat takes the column-independent
// values from `rf` (see RowFlat).
template <bool kAniso, bool kFlat>
[[gnu::always_inline]] inline void shade4(const v4d& a, const RowConsts& k, const RowFlat& rf, Lanes& o) {
  const v4d dx = k.rx + a * k.Lx, dy = k.ry + a * k.Ly;
  v4d dz, t, ky, s, lx2;
  if constexpr (kFlat) {
    dz = v4d{} + rf.dz;
    t = v4d{} + rf.t;
    ky = v4d{} + rf.ky;
    s = v4d{} + rf.s;
    lx2 = v4d{} + rf.lx2;
  } else {
    dz = k.rz + a * k.Lz;
    const v4d r = 1.0 / dz;
    t = -k.oz * r;
    const v4d kx = k.Lz * r;
    ky = k.Uz * r;
    s = t * t * k.tpm2;
    const v4d ax = kx * dx - k.Lx, ay = kx * dy - k.Ly;
    lx2 = s * (ax * ax + ay * ay);
  }
  const v4d bx = ky * dx - k.Ux, by = ky * dy - k.Uy;
  const v4d ly2 = s * (bx * bx + by * by);
  const v4d major = lx2 > ly2 ? lx2 : ly2;
  v4d q = major;
  if constexpr (kAniso) {
    const v4d minor = lx2 > ly2 ? ly2 : lx2, am = major * k.inv_a2;
    q = minor > am ? minor : am;
  }
  const v4d qmin = v4d{} + kMinFootprint2, qmax = v4d{} + kMaxFootprint2;
  q = q >= qmin ? q : qmin;  // also NaN -> min (as lod_from_lengths2)
  q = q > qmax ? qmax : q;
  o.dz = dz;
  o.t = t;
  o.tu = (k.ox + t * dx) * k.tpm;
  o.tv = (k.oy + t * dy) * k.tpm;
  o.q = q;
}


// Batch values of n columns (reads ceil(n/4)·4 entries of a: column arrays are padded).
template <bool kAniso>
[[gnu::always_inline]] inline void fill_batch_t(Batch& b, const double* a, int n, const RowConsts& k) {
  for (int j = 0; j < n; j += 4) {
    Lanes o;
    v4d av;
    load4(a + j, av);
    shade4<kAniso, false>(av, k, RowFlat{}, o);
    store4(b.dz + j, o.dz);
    store4(b.t + j, o.t);
    store4(b.tu + j, o.tu);
    store4(b.tv + j, o.tv);
    store4(b.q + j, o.q);
  }
}
VTSIM_CLONES_AVX2 void fill_batch(Batch& b, const double* a, int n, const RowConsts& k,
                                                                  bool aniso) {
  if (aniso) fill_batch_t<true>(b, a, n, k);
  else fill_batch_t<false>(b, a, n, k);
}

// Per-frame constants of the plane, shared by render, render_spans and render_pixels: one code
// path computes every sample, so the three agree bit for bit.
struct PlaneFrame {
  LodRule rule;
  double oz, ox, oy, tpm, tpm2, t_near, t_far, tw, th, inv_a2;
  std::int64_t W, H;
  int div, bw, bh;
  bool aniso;

  PlaneFrame(const Camera& cam, const ViewParams& p, const GroundTexture& tex, double z) {
    validate_view_params(p);
    rule = detail::lod_rule(p);
    oz = cam.pos_m.z - z;
    ox = cam.pos_m.x - tex.x0_m;
    oy = cam.pos_m.y - tex.y0_m;
    tpm = tex.texels_per_m;
    tpm2 = tpm * tpm;
    t_near = p.near_m / cam.focal_px;  // view depth = t·focal_px
    t_far = p.far_m / cam.focal_px;
    W = tex.extent.width;
    H = tex.extent.height;
    tw = static_cast<double>(W);
    th = static_cast<double>(H);
    div = p.divisor;
    bw = buffer_extent(cam.width, div);
    bh = buffer_extent(cam.height, div);
    aniso = rule.anisotropic;
    inv_a2 = rule.inv_aniso2;
  }
  glm::dvec3 row(const Camera& cam, int by) const {
    const double py = sample_pos(by, div, cam.height);
    return cam.focal_px * cam.fwd + (cam.cy - py) * cam.up;
  }
  // A row whose two end rays miss the plane is sky throughout (d.z is linear along a row and its
  // rounded evaluation monotone).
  bool sky_row(const Camera& cam, const glm::dvec3& r, const double* col) const {
    const double dz_first = r.z + col[0] * cam.left.z, dz_last = r.z + col[bw - 1] * cam.left.z;
    return oz != 0.0 && dz_first * oz >= 0.0 && dz_last * oz >= 0.0;
  }
  RowConsts consts(const Camera& cam, const glm::dvec3& r) const {
    return RowConsts{r.x,      r.y,      r.z,      cam.left.x, cam.left.y, cam.left.z, cam.up.x, cam.up.y,
                     cam.up.z, ox,       oy,       oz,         tpm,        tpm2,       inv_a2};
  }
  void fill(Batch& b, const double* a, int n, const glm::dvec3& r, const Camera& cam) const {
    fill_batch(b, a, n, consts(cam, r), aniso);
  }
  // True when batch entry j is a sample; otherwise counts why not and returns false.
  bool classify(const Batch& b, int j, ViewCounters& c) const {
    const double dz = b.dz[j], t = b.t[j];
    if (!(dz * oz < 0.0)) {  // parallel, pointing away from the plane, or camera on it
      if (oz == 0.0 && dz != 0.0) ++c.clipped;  // hit at depth 0 < near
      else ++c.sky;
      return false;
    }
    if (!(t >= t_near && t <= t_far)) {
      ++c.clipped;
      return false;
    }
    if (oz < 0.0) {  // camera below the plane sees its back
      ++c.backfacing;
      return false;
    }
    const double tu = b.tu[j], tv = b.tv[j];
    if (!(tu >= 0.0 && tu < tw && tv >= 0.0 && tv < th)) {
      ++c.outside_texture;
      return false;
    }
    return true;
  }
  ViewSample sample(const Batch& b, int j, std::uint32_t pixel) const {
    std::int64_t u = static_cast<std::int64_t>(b.tu[j]), v = static_cast<std::int64_t>(b.tv[j]);
    if (u >= W) u = W - 1;  // within an ulp of W above 2^53
    if (v >= H) v = H - 1;
    const double lod = 0.5 * fast_log2(b.q[j]) + rule.bias;
    return ViewSample{u, v, static_cast<float>(lod), pixel};
  }
};

// cx − px of each buffer column, per thread; padded with 8 copies of the last so that groups of
// four starting anywhere in the row stay inside.
const double* column_offsets(const Camera& cam, int div, int bw) {
  thread_local std::vector<double> col;
  col.resize(static_cast<std::size_t>(bw) + 8);
  for (int bx = 0; bx < bw; ++bx) col[static_cast<std::size_t>(bx)] = cam.cx - sample_pos(bx, div, cam.width);
  for (std::size_t i = static_cast<std::size_t>(bw); i < col.size(); ++i) col[i] = col[static_cast<std::size_t>(bw) - 1];
  return col.data();
}

// Where render_spans writes, across rows.
struct SpanOut {
  std::vector<ViewSpan>& spans;
  ViewCounters& c;
  std::uint32_t& n_samples;
  const LevelCuts& cuts;
  int levels, block_shift;
  int last_level = 0;
};

// Opens a span at the sample in batch entry j. Its level is where q falls among the level cuts
// (the level sample() would give, without the logarithm), searched from the last span's level.
void open_span(const PlaneFrame& fr, const Batch& b, int j, std::uint32_t pixel, SpanOut& o, SpanBounds& k) {
  std::int64_t u = static_cast<std::int64_t>(b.tu[j]), v = static_cast<std::int64_t>(b.tv[j]);
  if (u >= fr.W) u = fr.W - 1;  // as sample()
  if (v >= fr.H) v = fr.H - 1;
  const int level = cut_level(o.cuts, b.q[j], o.last_level, o.levels);
  o.last_level = level;
  o.spans.push_back(ViewSpan{u, u, v, v, pixel, 1, o.n_samples, level});
  ++o.n_samples;
  k = span_bounds(o.cuts, level, u, v, o.block_shift, fr.tw, fr.th);
}

// Without roll, a whole run of g columns [x, x + g) at once. Every quantity of the span test is
// then a chain of rounded operations each monotone in the one input that varies along the row
// (the column offset a; d.z, t, s and lx2 are the row's), so the computed tu and tv of the run lie
// between those of its two end columns, and bounds of the computed q follow from interval
// arithmetic with the same rounded operations at the interval ends (a rounded monotone operation
// keeps the order of its inputs; the square of an interval through 0 starts at 0). If the bounds
// lie inside the open span's test, every column passes: the span takes the run whole, with the
// exact bounding box (truncation of the end values). Returns false to let the caller go lane by
// lane.
template <bool kAniso>
[[gnu::always_inline]] inline bool flat_run(const RowConsts& k, const RowFlat& rf, const double* col, int x, int g,
                                            const SpanBounds& b, ViewSpan& sp) {
  const double a0 = col[x], a1 = col[x + g - 1];
  const double dx0 = k.rx + a0 * k.Lx, dx1 = k.rx + a1 * k.Lx;
  const double dy0 = k.ry + a0 * k.Ly, dy1 = k.ry + a1 * k.Ly;
  const double tu0 = (k.ox + rf.t * dx0) * k.tpm, tu1 = (k.ox + rf.t * dx1) * k.tpm;
  const double tv0 = (k.oy + rf.t * dy0) * k.tpm, tv1 = (k.oy + rf.t * dy1) * k.tpm;
  const double ulo = std::min(tu0, tu1), uhi = std::max(tu0, tu1), vlo = std::min(tv0, tv1), vhi = std::max(tv0, tv1);
  if (!(ulo >= b.u_lo && uhi < b.u_hi && vlo >= b.v_lo && vhi < b.v_hi)) return false;
  const auto square = [](double e0, double e1, double& lo, double& hi) {
    const double s0 = e0 * e0, s1 = e1 * e1;
    lo = (e0 <= 0.0) != (e1 <= 0.0) || e0 == 0.0 || e1 == 0.0 ? 0.0 : std::min(s0, s1);
    hi = std::max(s0, s1);
  };
  double bx_lo, bx_hi, by_lo, by_hi;
  square(rf.ky * dx0 - k.Ux, rf.ky * dx1 - k.Ux, bx_lo, bx_hi);
  square(rf.ky * dy0 - k.Uy, rf.ky * dy1 - k.Uy, by_lo, by_hi);
  const auto q_of = [&](double sum) {  // shade4's q from ly2's sum, scalar
    const double lx2 = rf.lx2, ly2 = rf.s * sum;
    const double major = lx2 > ly2 ? lx2 : ly2;
    double q = major;
    if constexpr (kAniso) {
      const double minor = lx2 > ly2 ? ly2 : lx2, am = major * k.inv_a2;
      q = minor > am ? minor : am;
    }
    q = q >= kMinFootprint2 ? q : kMinFootprint2;
    return q > kMaxFootprint2 ? kMaxFootprint2 : q;
  };
  if (!(q_of(bx_lo + by_lo) >= b.q_lo && q_of(bx_hi + by_hi) < b.q_hi)) return false;
  sp.count += static_cast<std::uint32_t>(g);
  sp.u_lo = std::min(sp.u_lo, static_cast<std::int64_t>(ulo));
  sp.u_hi = std::max(sp.u_hi, static_cast<std::int64_t>(uhi));
  sp.v_lo = std::min(sp.v_lo, static_cast<std::int64_t>(vlo));
  sp.v_hi = std::max(sp.v_hi, static_cast<std::int64_t>(vhi));
  return true;
}

// One row of render_spans, four columns at a time: the arithmetic of shade4, then the open span's
// test on all four lanes at once. A group whose four samples all stay in the span only widens the
// span's running bounding box (kept in vectors, folded into the span when the group test
// fails); any other group goes through the lanes one by one, exactly as render() would.
// Inlined into each target clone of span_row (a separate function would be compiled for the
// default target only).
template <bool kAniso, bool kFlat>
[[gnu::always_inline]] inline void span_row_t(const PlaneFrame& fr, const RowConsts& rc, const double* col, int by, SpanOut& o) {
  const RowFlat rf = kFlat ? row_flat(rc, col[0]) : RowFlat{};
  thread_local Batch b;
  SpanBounds k{};
  bool open = false;
  detail::RunBox box;
  const auto fold = [&]() __attribute__((always_inline)) {
    if (box.run != 0) o.n_samples += box.fold(o.spans.back());
  };
  const double oz = fr.oz, tn = fr.t_near, tf = fr.t_far;
  const int bw = fr.bw;
  int g = 32;  // flat runs: doubled after a run that passes, halved after one that does not
  for (int x = 0; x < bw; x += 4) {
    if constexpr (kFlat) {
      while (open && g >= 8 && x + g <= bw) {
        if (flat_run<kAniso>(rc, rf, col, x, g, k, o.spans.back())) {
          o.n_samples += static_cast<std::uint32_t>(g);
          x += g;
          g = g < 128 ? 2 * g : g;
        } else {
          g /= 2;
        }
      }
      if (g < 8) g = 8;
      if (x >= bw) break;
    }
    Lanes l;
    v4d av;
    load4(col + x, av);
    shade4<kAniso, kFlat>(av, rc, rf, l);
    if (open && x + 4 <= bw) {
      // Without roll d.z and t are the row's (RowFlat), and a span is open only if they passed.
      simd::v4i ray = simd::v4i{} - 1;
      if constexpr (!kFlat) ray = (l.dz * oz < 0.0) & (l.t >= tn) & (l.t <= tf);
      if (detail::all_in_span(k, l.q, l.tu, l.tv, ray)) {
        box.add(l.tu, l.tv);
        continue;
      }
    }
    fold();
    store4(b.dz, l.dz);
    store4(b.t, l.t);
    store4(b.tu, l.tu);
    store4(b.tv, l.tv);
    store4(b.q, l.q);
    const int n = bw - x < 4 ? bw - x : 4;
    for (int j = 0; j < n; ++j) {
      if (open && (b.dz[j] * oz < 0.0) && b.t[j] >= tn && b.t[j] <= tf && b.q[j] >= k.q_lo && b.q[j] < k.q_hi &&
          b.tu[j] >= k.u_lo && b.tu[j] < k.u_hi && b.tv[j] >= k.v_lo && b.tv[j] < k.v_hi) {
        const std::int64_t u = static_cast<std::int64_t>(b.tu[j]), v = static_cast<std::int64_t>(b.tv[j]);
        detail::widen(o.spans.back(), u, u, v, v, 1);
        ++o.n_samples;
        continue;
      }
      open = false;
      if (!fr.classify(b, j, o.c)) continue;
      open_span(fr, b, j, static_cast<std::uint32_t>(by * bw + x + j), o, k);
      open = true;
    }
  }
  fold();
}
VTSIM_CLONES_AVX2 void span_row(const PlaneFrame& fr, const RowConsts& rc,
                                                                const double* col, int by, SpanOut& o) {
  const bool flat = rc.Lz == 0.0 && rc.rz != 0.0;
  if (fr.aniso) {
    if (flat) span_row_t<true, true>(fr, rc, col, by, o);
    else span_row_t<true, false>(fr, rc, col, by, o);
  } else {
    if (flat) span_row_t<false, true>(fr, rc, col, by, o);
    else span_row_t<false, false>(fr, rc, col, by, o);
  }
}


// Level runs of the valid rows without roll, for render_spans on a camera that only translates.
// In such a row (RowFlat) q depends on the row's and column's ray only: the camera orientation,
// intrinsics, the height above the plane and the view parameters — not on its x, y (which enter
// tu and tv only). So two frames with the same bits of those inputs have the same q bits at every
// pixel, hence the same levels, and a row is a list of runs of one level. Only tu and tv move:
// each is monotone along the row (flat_run's argument), so within a level run the pixels in one
// block form one interval of columns, as do those outside the texture, and a span's end is found
// by a few evaluations of tu and tv at single columns instead of every column.
struct LevelRun {
  int x_end;  // columns [previous run's x_end (0 first), x_end) are at `level`
  int level;
};
struct FlatRuns {
  static constexpr int kKey = 27;
  std::uint64_t key[kKey] = {};
  bool valid = false;  // key holds a frame's inputs
  bool built = false;  // rows/runs hold the level runs of that key
  std::uint64_t last_use = 0;
  std::vector<std::uint32_t> row_begin;  // row r's runs are runs[row_begin[r], row_begin[r + 1]); empty: not a flat valid row
  std::vector<LevelRun> runs;
};

// Every input of q and of the row classes, bit for bit (see FlatRuns).
void flat_key(const Camera& cam, const ViewParams& p, const PlaneFrame& fr, int levels, std::uint64_t* key) {
  const double v[] = {cam.fwd.x, cam.fwd.y, cam.fwd.z, cam.left.x, cam.left.y, cam.left.z, cam.up.x, cam.up.y, cam.up.z,
                      cam.focal_px, cam.cx, cam.cy, fr.oz, fr.tpm, fr.tpm2, fr.inv_a2, fr.t_near, fr.t_far, fr.rule.bias};
  int i = 0;
  for (const double d : v) key[i++] = std::bit_cast<std::uint64_t>(d);
  key[i++] = static_cast<std::uint64_t>(cam.width);
  key[i++] = static_cast<std::uint64_t>(cam.height);
  key[i++] = static_cast<std::uint64_t>(p.divisor);
  key[i++] = static_cast<std::uint64_t>(fr.aniso);
  key[i++] = static_cast<std::uint64_t>(levels);
  key[i++] = static_cast<std::uint64_t>(fr.bw);
  key[i++] = static_cast<std::uint64_t>(fr.bh);
  key[i++] = 0;
}

// The cache entry for this frame's key, per thread: two entries, so that a replay rendering the
// feedback and the pop-in buffers at different divisors keeps both.
FlatRuns& flat_runs_for(const std::uint64_t* key, bool& seen) {
  thread_local FlatRuns entries[2];
  thread_local std::uint64_t clock = 0;
  ++clock;
  for (FlatRuns& e : entries)
    if (e.valid && std::equal(key, key + FlatRuns::kKey, e.key)) {
      e.last_use = clock;
      seen = true;
      return e;
    }
  seen = false;
  FlatRuns& e = entries[0].last_use <= entries[1].last_use ? entries[0] : entries[1];
  std::copy(key, key + FlatRuns::kKey, e.key);
  e.valid = true;
  e.built = false;
  e.last_use = clock;
  return e;
}

// A row without roll whose every pixel passes classify's ray tests (d.z sign, near/far, front
// face): only the texture test can fail, column by column.
bool flat_valid_row(const PlaneFrame& fr, const RowConsts& rc, const RowFlat& rf) {
  return rc.Lz == 0.0 && rc.rz != 0.0 && rf.dz * fr.oz < 0.0 && rf.t >= fr.t_near && rf.t <= fr.t_far && !(fr.oz < 0.0);
}

// Appends the level runs of a flat valid row: shade4's q at every column, located among the cuts.
template <bool kAniso>
[[gnu::always_inline]] inline void level_runs_t(const RowConsts& rc, const RowFlat& rf, const double* col, int bw,
                                                const LevelCuts& cuts, int levels, std::vector<LevelRun>& out) {
  int level = -1;
  for (int x = 0; x < bw; x += 4) {
    Lanes l;
    v4d av;
    load4(col + x, av);
    shade4<kAniso, true>(av, rc, rf, l);
    const int n = bw - x < 4 ? bw - x : 4;
    for (int j = 0; j < n; ++j) {
      const double q = l.q[j];
      if (level >= 0 && q >= cuts.cut[level] && q < cuts.cut[level + 1]) continue;
      if (level >= 0) out.push_back(LevelRun{x + j, level});
      level = cut_level(cuts, q, level < 0 ? 0 : level, levels);
    }
  }
  out.push_back(LevelRun{bw, level});
}
VTSIM_CLONES_AVX2 void level_runs(const RowConsts& rc, const RowFlat& rf, const double* col,
                                                                  int bw, const LevelCuts& cuts, int levels, bool aniso,
                                                                  std::vector<LevelRun>& out) {
  if (aniso) level_runs_t<true>(rc, rf, col, bw, cuts, levels, out);
  else level_runs_t<false>(rc, rf, col, bw, cuts, levels, out);
}

// The first column in (x, xe] where `pred` fails (xe if none), given pred(x) and that pred holds
// on a prefix of [x, xe). Tries the predicted end `guess` first (pred at guess − 1, and at guess
// unless it is xe: right in almost every span, as the row's slope predicts the crossing), then
// gallops and bisects. lo only moves to a column pred just accepted, hi to one it just rejected,
// and the result is hi = lo + 1: pred's last acceptance (if any) was at the result − 1, its last
// rejection (if any) at the result.
template <class P>
int prefix_end(int x, int xe, int guess, P pred) {
  int lo = x, hi = xe;  // pred(lo); hi == xe or !pred(hi)
  guess = guess < x + 1 ? x + 1 : (guess > xe ? xe : guess);
  const int g1 = guess - 1;
  if (g1 > lo) {
    if (pred(g1)) lo = g1;
    else hi = g1;
  }
  if (lo == g1 && guess < xe) {
    if (!pred(guess)) return guess;
    lo = guess;
  }
  for (int step = 1; lo + step < hi; step *= 2) {
    if (!pred(lo + step)) {
      hi = lo + step;
      break;
    }
    lo += step;
  }
  while (hi - lo > 1) {
    const int mid = lo + (hi - lo) / 2;
    if (pred(mid)) lo = mid;
    else hi = mid;
  }
  return hi;
}

// One flat valid row from its level runs; the same spans, counts and counters as span_row.
void span_row_runs(const PlaneFrame& fr, const RowConsts& k, const RowFlat& rf, const double* col, int by,
                   const LevelRun* runs, const LevelRun* runs_end, SpanOut& o) {
  const int bw = fr.bw;
  const auto tu_at = [&](int x) { return (k.ox + rf.t * (k.rx + col[x] * k.Lx)) * k.tpm; };
  const auto tv_at = [&](int x) { return (k.oy + rf.t * (k.ry + col[x] * k.Ly)) * k.tpm; };
  // Reciprocal slopes per column for the guesses (hints only: every end is checked).
  const double iu = bw > 1 ? (bw - 1) / (tu_at(bw - 1) - tu_at(0)) : 0.0;
  const double iv = bw > 1 ? (bw - 1) / (tv_at(bw - 1) - tv_at(0)) : 0.0;
  const auto guess_exit = [](double t, double inv_slope, double lo, double hi) {  // columns until t leaves [lo, hi)
    if (inv_slope > 0.0) return (hi - t) * inv_slope;
    if (inv_slope < 0.0) return (lo - t) * inv_slope;
    return static_cast<double>(INFINITY);
  };
  const auto to_col = [](int x, double n, int xe) {
    if (!(n < static_cast<double>(xe - x))) return xe;
    return x + 1 + (n > 0.0 ? static_cast<int>(n) : 0);
  };
  // The columns inside the texture: tu and tv each in range on an interval of columns (monotone).
  int in0 = 0, in1 = bw;
  const auto clip_axis = [&](auto f, double extent) {
    const double f0 = f(0), f1 = f(bw - 1);
    if (f0 >= 0.0 && f0 < extent && f1 >= 0.0 && f1 < extent) return;  // the whole row
    const auto first_true = [&](auto pred) {  // pred monotone false → true over the columns
      int lo = 0, hi = bw;
      while (lo < hi) {
        const int mid = lo + (hi - lo) / 2;
        if (pred(mid)) hi = mid;
        else lo = mid + 1;
      }
      return lo;
    };
    if (f0 <= f1) {  // non-decreasing
      in0 = std::max(in0, first_true([&](int c) { return f(c) >= 0.0; }));
      in1 = std::min(in1, first_true([&](int c) { return !(f(c) < extent); }));
    } else {
      in0 = std::max(in0, first_true([&](int c) { return f(c) < extent; }));
      in1 = std::min(in1, first_true([&](int c) { return !(f(c) >= 0.0); }));
    }
  };
  clip_axis(tu_at, fr.tw);
  clip_axis(tv_at, fr.th);
  if (in1 < in0) in1 = in0;
  o.c.outside_texture += static_cast<std::uint64_t>(bw - (in1 - in0));
  int x = in0;
  // tu, tv at column `known`: pred's last rejection, which is where the next span starts
  // (prefix_end's hi only moves to rejected columns).
  int known = -1;
  double known_u = 0.0, known_v = 0.0;
  for (const LevelRun* r = runs; r != runs_end && x < in1; ++r) {
    const int xe = std::min(r->x_end, in1), level = r->level;
    while (x < xe) {
      const double tu = x == known ? known_u : tu_at(x), tv = x == known ? known_v : tv_at(x);
      std::int64_t u = static_cast<std::int64_t>(tu), v = static_cast<std::int64_t>(tv);
      if (u >= fr.W) u = fr.W - 1;  // as open_span
      if (v >= fr.H) v = fr.H - 1;
      SpanBounds bb;
      block_bounds(u, v, level + o.block_shift, fr.tw, fr.th, bb);  // as open_span
      const double ulo = bb.u_lo, uhi = bb.u_hi, vlo = bb.v_lo, vhi = bb.v_hi;
      const double n = std::min(guess_exit(tu, iu, ulo, uhi), guess_exit(tv, iv, vlo, vhi));
      double last_u = tu, last_v = tv;  // at the greatest column pred accepted: e − 1 when it returns
      const int e = prefix_end(x, xe, to_col(x, n, xe), [&](int c) {
        const double cu = tu_at(c), cv = tv_at(c);
        if (!(cu >= ulo && cu < uhi && cv >= vlo && cv < vhi)) {
          known = c;
          known_u = cu;
          known_v = cv;
          return false;
        }
        last_u = cu;
        last_v = cv;
        return true;
      });
      ViewSpan sp{u, u, v, v, static_cast<std::uint32_t>(by * bw + x), static_cast<std::uint32_t>(e - x), o.n_samples, level};
      if (e - x > 1) {  // the run's texels lie between those of its ends (monotone)
        const std::int64_t ul = static_cast<std::int64_t>(last_u), vl = static_cast<std::int64_t>(last_v);
        sp.u_lo = std::min(sp.u_lo, ul);
        sp.u_hi = std::max(sp.u_hi, ul);
        sp.v_lo = std::min(sp.v_lo, vl);
        sp.v_hi = std::max(sp.v_hi, vl);
      }
      o.spans.push_back(sp);
      o.n_samples += sp.count;
      o.last_level = level;
      x = e;
    }
  }
}

}  // namespace

// The plane is the hot case of the benchmark target (≈ 7.7 ns per sample at divisor 8), so the
// ray differentials are specialised for n = +z: with d the sample's ray, r = 1/d.z and the hit
// at t = −o.z·r, one pixel right moves the hit by t·(−L + (L.z·r)·d) and one pixel down by
// t·(−U + (U.z·r)·d) (lod.h, Igehy's plane differential with n = z). Each sample is computed from
// its own row and column only, so a buffer of any divisor reproduces divisor 1's values bit for
// bit. Rows whose two end rays both miss the plane are sky throughout and cost O(1).
void PlaneScene::render(const Camera& cam, const ViewParams& p, ViewBuffer& out) const {
  detail::begin_frame(cam, p, out);
  const PlaneFrame fr(cam, p, tex_, z_);
  const double* col = column_offsets(cam, fr.div, fr.bw);
  thread_local Batch b;
  ViewCounters c;
  for (int by = 0; by < fr.bh; ++by) {
    const glm::dvec3 row = fr.row(cam, by);
    if (fr.sky_row(cam, row, col)) {
      c.sky += static_cast<std::uint64_t>(fr.bw);
      continue;
    }
    for (int x0 = 0; x0 < fr.bw; x0 += kChunk) {
      const int n = fr.bw - x0 < kChunk ? fr.bw - x0 : kChunk;
      fr.fill(b, col + x0, n, row, cam);
      for (int j = 0; j < n; ++j)
        if (fr.classify(b, j, c)) out.samples.push_back(fr.sample(b, j, static_cast<std::uint32_t>(by * fr.bw + x0 + j)));
    }
  }
  out.counters = c;
}

void PlaneScene::render_pixels(const SpanBuffer& sb, std::uint32_t pixel, std::uint32_t count,
                               std::vector<ViewSample>& out) const {
  const Camera& cam = sb.cam;
  const ViewParams& p = sb.params;
  const PlaneFrame fr(cam, p, tex_, z_);
  const std::uint32_t bw = static_cast<std::uint32_t>(fr.bw);
  if (pixel / bw >= static_cast<std::uint32_t>(fr.bh) || pixel % bw + count > bw)
    throw std::invalid_argument("render_pixels: the pixels are not within one buffer row");
  const int by = static_cast<int>(pixel / bw), xb = static_cast<int>(pixel % bw);
  const double* col = column_offsets(cam, fr.div, fr.bw);
  const glm::dvec3 row = fr.row(cam, by);
  thread_local Batch b;
  ViewCounters c;
  for (int x0 = xb; x0 < xb + static_cast<int>(count); x0 += kChunk) {
    const int n = xb + static_cast<int>(count) - x0 < kChunk ? xb + static_cast<int>(count) - x0 : kChunk;
    fr.fill(b, col + x0, n, row, cam);
    for (int j = 0; j < n; ++j) {
      if (!fr.classify(b, j, c)) throw std::logic_error("render_pixels: a pixel of the span is not a sample");
      out.push_back(fr.sample(b, j, static_cast<std::uint32_t>(by * fr.bw + x0 + j)));
    }
  }
}

void PlaneScene::render_spans(const Camera& cam, const ViewParams& p, SpanBuffer& out) const {
  const PlaneFrame fr(cam, p, tex_, z_);
  const int levels = mip_level_count(tex_.extent);
  const LevelCuts& cuts = level_cuts(fr.rule.bias, levels);
  // The per-sample buffer is wanted anyway, or the level cuts are not trustworthy: derive the
  // spans from render()'s samples.
  if (out.keep_samples || !cuts.ok) {
    IScene::render_spans(cam, p, out);
    return;
  }
  if (out.block_shift < 0 || out.block_shift > 62) throw std::invalid_argument("spans: block_shift must be in [0, 62]");
  out.width = fr.bw;
  out.height = fr.bh;
  out.divisor = fr.div;
  out.levels = levels;
  out.spans.clear();
  out.samples = 0;
  out.has_samples = false;
  out.view.samples.clear();
  out.scene = this;
  out.cam = cam;
  out.params = p;
  const double* col = column_offsets(cam, fr.div, fr.bw);
  ViewCounters c;
  std::uint32_t n_samples = 0;
  SpanOut so{out.spans, c, n_samples, cuts, levels, out.block_shift};
  // Level runs: used when this frame's key was built, built when it was seen on an earlier frame
  // (so a rotating camera, new every frame, pays only the key).
  std::uint64_t key[FlatRuns::kKey];
  flat_key(cam, p, fr, levels, key);
  bool seen = false;
  FlatRuns& fc = flat_runs_for(key, seen);
  const bool build = seen && !fc.built;
  if (build) {
    fc.row_begin.assign(static_cast<std::size_t>(fr.bh) + 1, 0);
    fc.runs.clear();
  }
  const bool use = fc.built || build;
  for (int by = 0; by < fr.bh; ++by) {
    const auto r = static_cast<std::size_t>(by);
    const glm::dvec3 row = fr.row(cam, by);
    if (fr.sky_row(cam, row, col)) {
      c.sky += static_cast<std::uint64_t>(fr.bw);
      if (build) fc.row_begin[r + 1] = static_cast<std::uint32_t>(fc.runs.size());
      continue;
    }
    const RowConsts rc = fr.consts(cam, row);
    if (use && rc.Lz == 0.0 && rc.rz != 0.0) {
      const RowFlat rf = row_flat(rc, col[0]);
      if (flat_valid_row(fr, rc, rf)) {
        if (build) level_runs(rc, rf, col, fr.bw, cuts, levels, fr.aniso, fc.runs);
        if (build) fc.row_begin[r + 1] = static_cast<std::uint32_t>(fc.runs.size());
        const LevelRun* b = fc.runs.data() + fc.row_begin[r];
        const LevelRun* e = fc.runs.data() + fc.row_begin[r + 1];
        if (b != e) {
          span_row_runs(fr, rc, rf, col, by, b, e, so);
          continue;
        }
      }
    }
    if (build) fc.row_begin[r + 1] = static_cast<std::uint32_t>(fc.runs.size());
    span_row(fr, rc, col, by, so);
  }
  if (build) fc.built = true;
  out.samples = n_samples;
  out.counters = c;
}

// The table's "plane" (scene.cpp).
std::unique_ptr<IScene> make_plane_scene(const SceneConfig& cfg, TextureExtent extent) {
  if (!std::isfinite(cfg.plane_z_m)) throw InputError("plane_z_m", "must be finite");
  return std::make_unique<PlaneScene>(GroundTexture{cfg.origin_x_m, cfg.origin_y_m, cfg.texels_per_m, extent}, cfg.plane_z_m);
}

}  // namespace vtsim
