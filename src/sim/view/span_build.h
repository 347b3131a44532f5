#pragma once
// Building spans (view_spans.h) straight from a renderer's per-sample values, without the
// logarithm (internal to src/sim; used by the plane's and the mesh's render_spans): the level cuts
// of the LOD rule, and the open span's test as double comparisons.
#include <algorithm>
#include <bit>
#include <cstdint>

#include "sim/view/simd.h"
#include "core/view_spans.h"

namespace vtsim::detail {

// Level cuts of the LOD rule: cut[k] = the least squared footprint q whose desired level
// desired_level(float(0.5·fast_log2(q) + bias), levels) is >= k. The level is a monotone step
// function of q (fast_log2 is monotone, so are the addition, the rounding to float and floor),
// so a sample is at level k exactly when cut[k] <= q < cut[k + 1]: the span test compares q and
// never takes a logarithm. Found by bisection over the bit patterns of positive doubles (ordered
// like the values) in [kMinFootprint2, kMaxFootprint2], the range the renderers clamp q to;
// cached per thread for the last (bias, levels), which a replay never changes. Monotonicity is
// what the cuts rest on; rounding could only break it within a few ulps of q around a cut (the
// LOD's rounding error is an ulp or two), so each cut is checked over ±256 ulps and a failed check
// (`ok` false) sends render_spans to the per-sample path rather than risk a wrong span.
struct LevelCuts {
  double bias = 0.0;
  int levels = 0;
  bool ok = true;
  double cut[66] = {};  // cut[0] = −inf; cut[k] for k in [1, levels]; +inf where no q reaches k
};
const LevelCuts& level_cuts(double bias, int levels);

// The level whose cuts hold q, searched from `from` (the previous span's: neighbours usually agree).
inline int cut_level(const LevelCuts& c, double q, int from, int levels) {
  int level = from;
  while (level > 0 && q < c.cut[level]) --level;
  while (level + 1 < levels && q >= c.cut[level + 1]) ++level;
  return level;
}

// The open span's test: a sample at the span's level (q in [q_lo, q_hi)) whose continuous texel
// coordinates lie in the span's block (tu in [u_lo, u_hi), tv in [v_lo, v_hi)). The block bounds
// are clipped to the texture, so the texture test is included.
struct SpanBounds {
  double q_lo, q_hi, u_lo, u_hi, v_lo, v_hi;
};

// True when four samples all pass the span's test and the caller's own lane conditions `also`.
[[gnu::always_inline]] inline bool all_in_span(const SpanBounds& b, const simd::v4d& q, const simd::v4d& tu,
                                               const simd::v4d& tv, const simd::v4i& also) {
  simd::v4i m = also & (q >= b.q_lo) & (q < b.q_hi) & (tu >= b.u_lo) & (tu < b.u_hi) & (tv >= b.v_lo) & (tv < b.v_hi);
  m &= __builtin_shufflevector(m, m, 2, 3, 0, 1);  // all four lanes set: reduce in registers
  m &= __builtin_shufflevector(m, m, 1, 0, 3, 2);
  return m[0] != 0;
}

// The texel range of the 2^sh-texel block holding level-0 texel (u, v), as spans_from_samples
// defines blocks (sh = level + block_shift; from 63 on, one block covers every texel), clipped to
// [0, tw) × [0, th).
inline void block_bounds(std::int64_t u, std::int64_t v, int sh, double tw, double th, SpanBounds& b) {
  if (sh >= 63) {
    b.u_lo = b.v_lo = 0.0;
    b.u_hi = tw;
    b.v_hi = th;
    return;
  }
  const std::int64_t bu = u >> sh, bv = v >> sh;
  const double p2 = std::bit_cast<double>(static_cast<std::uint64_t>(1023 + sh) << 52);  // 2^sh, exact
  b.u_lo = std::max(0.0, static_cast<double>(bu) * p2);
  b.u_hi = std::min(tw, static_cast<double>(bu + 1) * p2);
  b.v_lo = std::max(0.0, static_cast<double>(bv) * p2);
  b.v_hi = std::min(th, static_cast<double>(bv + 1) * p2);
}

// The test of a span opened at texel (u, v) at `level`.
inline SpanBounds span_bounds(const LevelCuts& c, int level, std::int64_t u, std::int64_t v, int block_shift, double tw,
                              double th) {
  SpanBounds b;
  b.q_lo = c.cut[level];
  b.q_hi = c.cut[level + 1];
  block_bounds(u, v, level + block_shift, tw, th, b);
  return b;
}

// Adds n samples whose texels lie in [u_lo, u_hi] × [v_lo, v_hi] to span sp.
[[gnu::always_inline]] inline void widen(ViewSpan& sp, std::int64_t u_lo, std::int64_t u_hi, std::int64_t v_lo,
                                         std::int64_t v_hi, std::uint32_t n) {
  sp.u_lo = std::min(sp.u_lo, u_lo);
  sp.u_hi = std::max(sp.u_hi, u_hi);
  sp.v_lo = std::min(sp.v_lo, v_lo);
  sp.v_hi = std::max(sp.v_hi, v_hi);
  sp.count += n;
}

// Groups of four samples that passed the open span's test, not yet folded into the span: the box
// of their continuous texel coordinates, lane-wise. Inlined into each target clone of the span
// loops: an out-of-line call from an AVX2 clone into default code leaves the upper register
// halves dirty for the SSE code after it (the mesh's rasteriser ran 1.7x slower that way).
struct RunBox {
  simd::v4d umin{}, umax{}, vmin{}, vmax{};
  std::uint32_t run = 0;  // samples in the box; 0: empty

  [[gnu::always_inline]] inline void add(const simd::v4d& tu, const simd::v4d& tv) {
    if (run == 0) {
      umin = umax = tu;
      vmin = vmax = tv;
    } else {
      umin = tu < umin ? tu : umin;
      umax = tu > umax ? tu : umax;
      vmin = tv < vmin ? tv : vmin;
      vmax = tv > vmax ? tv : vmax;
    }
    run += 4;
  }
  // Widens sp by the box (non-empty; coordinates >= 0, so truncation is the texel index and is
  // monotone), empties it and returns the samples it held.
  [[gnu::always_inline]] inline std::uint32_t fold(ViewSpan& sp) {
    const double ul = std::min(std::min(umin[0], umin[1]), std::min(umin[2], umin[3]));
    const double uh = std::max(std::max(umax[0], umax[1]), std::max(umax[2], umax[3]));
    const double vl = std::min(std::min(vmin[0], vmin[1]), std::min(vmin[2], vmin[3]));
    const double vh = std::max(std::max(vmax[0], vmax[1]), std::max(vmax[2], vmax[3]));
    widen(sp, static_cast<std::int64_t>(ul), static_cast<std::int64_t>(uh), static_cast<std::int64_t>(vl),
          static_cast<std::int64_t>(vh), run);
    const std::uint32_t n = run;
    run = 0;
    return n;
  }
};

}  // namespace vtsim::detail
