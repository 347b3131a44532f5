#include "sim/scene_plane.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "sim/render_util.h"

namespace vtsim {

namespace {

constexpr int kChunk = 64;  // pixels per vectorised batch: arrays stay in L1, loops long enough

// Per-pixel values of one batch of a row, computed branch-free so that the compiler vectorises
// them; classification and the logarithm follow in a scalar pass.
struct Batch {
  alignas(32) double dz[kChunk];
  alignas(32) double t[kChunk];
  alignas(32) double tu[kChunk];  // continuous level-0 texel coordinates of the hit
  alignas(32) double tv[kChunk];
  alignas(32) double q[kChunk];   // squared footprint for the LOD rule, clamped
};

// Branch-free per-pixel arithmetic of a batch (vectorised by the compiler).
template <bool kAniso>
void fill_batch(Batch& b, const double* a, int n, const glm::dvec3& row, const glm::dvec3& L, const glm::dvec3& U,
                double ox, double oy, double oz, double tpm, double tpm2, double inv_a2) {
  const double Lx = L.x, Ly = L.y, Lz = L.z, Ux = U.x, Uy = U.y, Uz = U.z;
  const double rx = row.x, ry = row.y, rz = row.z;
  for (int j = 0; j < n; ++j) {
    const double dx = rx + a[j] * Lx, dy = ry + a[j] * Ly, dz = rz + a[j] * Lz;
    const double r = 1.0 / dz;
    const double t = -oz * r;
    const double kx = Lz * r, ky = Uz * r;
    const double ax = kx * dx - Lx, ay = kx * dy - Ly;
    const double bx = ky * dx - Ux, by = ky * dy - Uy;
    const double s = t * t * tpm2;
    const double lx2 = s * (ax * ax + ay * ay), ly2 = s * (bx * bx + by * by);
    const double major = lx2 > ly2 ? lx2 : ly2;
    double q = major;
    if constexpr (kAniso) {
      const double minor = lx2 > ly2 ? ly2 : lx2, am = major * inv_a2;
      q = minor > am ? minor : am;
    }
    q = q >= kMinFootprint2 ? q : kMinFootprint2;  // also NaN -> min (as lod_from_lengths2)
    q = q > kMaxFootprint2 ? kMaxFootprint2 : q;
    b.dz[j] = dz;
    b.t[j] = t;
    b.tu[j] = (ox + t * dx) * tpm;
    b.tv[j] = (oy + t * dy) * tpm;
    b.q[j] = q;
  }
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
  void fill(Batch& b, const double* a, int n, const glm::dvec3& r, const Camera& cam) const {
    if (aniso) fill_batch<true>(b, a, n, r, cam.left, cam.up, ox, oy, oz, tpm, tpm2, inv_a2);
    else fill_batch<false>(b, a, n, r, cam.left, cam.up, ox, oy, oz, tpm, tpm2, inv_a2);
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

// cx − px of each buffer column, per thread.
const double* column_offsets(const Camera& cam, int div, int bw) {
  thread_local std::vector<double> col;
  col.resize(static_cast<std::size_t>(bw));
  for (int bx = 0; bx < bw; ++bx) col[static_cast<std::size_t>(bx)] = cam.cx - sample_pos(bx, div, cam.width);
  return col.data();
}

// Level cuts of the LOD rule: cut[k] = the least squared footprint q whose desired level
// desired_level(float(0.5·fast_log2(q) + bias), levels) is >= k. The level is a monotone step
// function of q (fast_log2 is monotone, so are the addition, the rounding to float and floor),
// so a sample is at level k exactly when cut[k] <= q < cut[k + 1]: the span test compares q and
// never takes a logarithm. Found by bisection over the bit patterns of positive doubles (ordered
// like the values) in [kMinFootprint2, kMaxFootprint2], the range fill_batch clamps q to; cached
// per thread for the last (bias, levels), which a replay never changes. Monotonicity is what the
// cuts rest on; rounding could only break it within a few ulps of q around a cut (the LOD's
// rounding error is an ulp or two), so each cut is checked over ±kCheckUlps ulps and a failed
// check sends render_spans to the per-sample path (`ok` false) rather than risk a wrong span.
struct LevelCuts {
  double bias = 0.0;
  int levels = 0;
  bool ok = true;
  double cut[66] = {};
};
constexpr std::uint64_t kCheckUlps = 256;
int level_of_q(double q, double bias, int levels) {
  return desired_level(static_cast<float>(0.5 * fast_log2(q) + bias), levels);
}
const LevelCuts& level_cuts(double bias, int levels) {
  thread_local LevelCuts lc;
  if (lc.levels == levels && std::bit_cast<std::uint64_t>(lc.bias) == std::bit_cast<std::uint64_t>(bias)) return lc;
  lc.bias = bias;
  lc.levels = levels;
  lc.ok = true;
  const std::uint64_t lo_bits = std::bit_cast<std::uint64_t>(kMinFootprint2), hi_bits = std::bit_cast<std::uint64_t>(kMaxFootprint2);
  lc.cut[0] = -INFINITY;
  for (int k = 1; k <= levels; ++k) {
    if (level_of_q(kMinFootprint2, bias, levels) >= k) {
      lc.cut[k] = -INFINITY;
    } else if (level_of_q(kMaxFootprint2, bias, levels) < k) {
      lc.cut[k] = INFINITY;
    } else {  // level(lo) < k <= level(hi)
      std::uint64_t lo = lo_bits, hi = hi_bits;
      while (hi - lo > 1) {
        const std::uint64_t mid = lo + (hi - lo) / 2;
        if (level_of_q(std::bit_cast<double>(mid), bias, levels) >= k) hi = mid;
        else lo = mid;
      }
      lc.cut[k] = std::bit_cast<double>(hi);
      for (std::uint64_t d = 1; d <= kCheckUlps; ++d) {
        if (hi - d >= lo_bits && level_of_q(std::bit_cast<double>(hi - d), bias, levels) >= k) lc.ok = false;
        if (hi + d <= hi_bits && level_of_q(std::bit_cast<double>(hi + d), bias, levels) < k) lc.ok = false;
      }
    }
  }
  return lc;
}

// The open span's test, as double comparisons on the batch values: a sample (as classify) at
// the span's level (q in [q_lo, q_hi)) whose texel lies in the span's block (u in [u_lo, u_hi),
// bounds clipped to the texture, so the texture test is included).
struct SpanBounds {
  double q_lo, q_hi, u_lo, u_hi, v_lo, v_hi;
};

// Entries from j on (j < n) that pass the open span's test, up to the first that fails. Eight
// at a time with no branch inside (the compiler vectorises the block), then one by one.
int run_length(const Batch& b, int j, int n, const SpanBounds& k, double oz, double t_near, double t_far) {
  const auto in = [&](int i) {
    return (b.dz[i] * oz < 0.0) & (b.t[i] >= t_near) & (b.t[i] <= t_far) & (b.q[i] >= k.q_lo) & (b.q[i] < k.q_hi) &
           (b.tu[i] >= k.u_lo) & (b.tu[i] < k.u_hi) & (b.tv[i] >= k.v_lo) & (b.tv[i] < k.v_hi);
  };
  int i = j;
  while (i + 8 <= n) {
    bool all = true;
    for (int m = 0; m < 8; ++m) all &= in(i + m);
    if (!all) break;
    i += 8;
  }
  while (i < n && in(i)) ++i;
  return i - j;
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

void PlaneScene::render_pixels(const Camera& cam, const ViewParams& p, std::uint32_t pixel, std::uint32_t count,
                               std::vector<ViewSample>& out) const {
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
  thread_local Batch b;
  ViewCounters c;
  SpanBounds k{};
  std::uint32_t n_samples = 0;
  for (int by = 0; by < fr.bh; ++by) {
    const glm::dvec3 row = fr.row(cam, by);
    if (fr.sky_row(cam, row, col)) {
      c.sky += static_cast<std::uint64_t>(fr.bw);
      continue;
    }
    bool open = false;  // out.spans.back() may grow
    for (int x0 = 0; x0 < fr.bw; x0 += kChunk) {
      const int n = fr.bw - x0 < kChunk ? fr.bw - x0 : kChunk;
      fr.fill(b, col + x0, n, row, cam);
      int j = 0;
      while (j < n) {
        if (open) {
          const int len = run_length(b, j, n, k, fr.oz, fr.t_near, fr.t_far);
          if (len > 0) {
            double ulo = b.tu[j], uhi = ulo, vlo = b.tv[j], vhi = vlo;
            for (int i = j + 1; i < j + len; ++i) {
              ulo = b.tu[i] < ulo ? b.tu[i] : ulo;
              uhi = b.tu[i] > uhi ? b.tu[i] : uhi;
              vlo = b.tv[i] < vlo ? b.tv[i] : vlo;
              vhi = b.tv[i] > vhi ? b.tv[i] : vhi;
            }
            // Texels are the truncations (tu >= 0), and truncation is monotone.
            ViewSpan& s = out.spans.back();
            s.u_lo = std::min(s.u_lo, static_cast<std::int64_t>(ulo));
            s.u_hi = std::max(s.u_hi, static_cast<std::int64_t>(uhi));
            s.v_lo = std::min(s.v_lo, static_cast<std::int64_t>(vlo));
            s.v_hi = std::max(s.v_hi, static_cast<std::int64_t>(vhi));
            s.count += static_cast<std::uint32_t>(len);
            n_samples += static_cast<std::uint32_t>(len);
            j += len;
            if (j == n) break;
          }
          open = false;
        }
        if (!fr.classify(b, j, c)) {
          ++j;
          continue;
        }
        const ViewSample sm = fr.sample(b, j, static_cast<std::uint32_t>(by * fr.bw + x0 + j));
        const int level = desired_level(sm.lod, levels);
        out.spans.push_back(ViewSpan{sm.u, sm.u, sm.v, sm.v, sm.pixel, 1, n_samples, level});
        ++n_samples;
        k.q_lo = cuts.cut[level];
        k.q_hi = cuts.cut[level + 1];
        const int sh = level + out.block_shift;
        if (sh < 63) {  // the block's texel range, as spans_from_samples defines it
          const std::int64_t bu = sm.u >> sh, bv = sm.v >> sh;
          k.u_lo = std::max(0.0, std::ldexp(static_cast<double>(bu), sh));
          k.u_hi = std::min(fr.tw, std::ldexp(static_cast<double>(bu + 1), sh));
          k.v_lo = std::max(0.0, std::ldexp(static_cast<double>(bv), sh));
          k.v_hi = std::min(fr.th, std::ldexp(static_cast<double>(bv + 1), sh));
        } else {
          k.u_lo = k.v_lo = 0.0;
          k.u_hi = fr.tw;
          k.v_hi = fr.th;
        }
        open = true;
        ++j;
      }
    }
  }
  out.samples = n_samples;
  out.counters = c;
}

}  // namespace vtsim
