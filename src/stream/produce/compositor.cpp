#include "stream/produce/compositor.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>

#include "core/error.h"

// An avx2 clone beside the default (as sim/view/simd.h); integer code, so both give the same bits.
#if defined(VTSIM_NO_TARGET_CLONES)
#define VTSIM_PRODUCE_CLONES
#else
#define VTSIM_PRODUCE_CLONES __attribute__((target_clones("avx2", "default")))
#endif

namespace vtsim::produce {

int select_level(const Atlas& atlas, double m_per_texel, double period_m) {
  const double lod = lod_from_derivative(m_per_texel / period_m, atlas.side);
  const double l = std::floor(lod + 0.5);
  if (!(l > 0)) return 0;
  return static_cast<int>(std::min(l, static_cast<double>(atlas.max_level())));
}

double lod_from_derivative(double du_per_texel, int side) { return std::log2(std::fabs(du_per_texel) * side); }

std::uint32_t active_layers(const CompositeJob& job) {
  std::uint32_t act = 0;
  const double x0 = job.origin_x_m - job.border * job.m_per_texel;
  const double x1 = job.origin_x_m + (job.tile + job.border) * job.m_per_texel;
  const double y0 = job.origin_y_m - job.border * job.m_per_texel;
  const double y1 = job.origin_y_m + (job.tile + job.border) * job.m_per_texel;
  for (std::size_t i = 0; i < job.masks.size(); ++i) {
    const WeightMask& m = job.masks[i];
    // Mask texels whose bilinear support touches the rectangle: one texel of margin each side.
    const auto lo = [&](double w, double o) { return static_cast<int>(std::floor((w - o) / m.m_per_texel - 0.5)); };
    const int mx0 = std::clamp(lo(x0, m.origin_x_m), 0, m.width - 1), mx1 = std::clamp(lo(x1, m.origin_x_m) + 1, 0, m.width - 1);
    const int my0 = std::clamp(lo(y0, m.origin_y_m), 0, m.height - 1), my1 = std::clamp(lo(y1, m.origin_y_m) + 1, 0, m.height - 1);
    for (int y = my0; y <= my1; ++y)
      for (int x = mx0; x <= mx1; ++x)
        for (int c = 0; c < 4; ++c)
          if (m.rgba[(static_cast<std::size_t>(y) * static_cast<std::size_t>(m.width) + static_cast<std::size_t>(x)) * 4 + static_cast<std::size_t>(c)])
            act |= 1u << (4 * i + static_cast<std::size_t>(c));
  }
  act &= job.layers.size() >= 32 ? ~0u : ((1u << job.layers.size()) - 1u);
  return act ? act : 1u;
}

ProduceWork count_work(const CompositeJob& job) {
  ProduceWork w;
  const std::uint64_t side = static_cast<std::uint64_t>(job.tile + 2 * job.border);
  w.texels = side * side;
  w.layers = static_cast<std::uint32_t>(std::popcount(active_layers(job)));
  const double x0 = job.origin_x_m - job.border * job.m_per_texel, x1 = job.origin_x_m + (job.tile + job.border) * job.m_per_texel;
  const double y0 = job.origin_y_m - job.border * job.m_per_texel, y1 = job.origin_y_m + (job.tile + job.border) * job.m_per_texel;
  for (const Decal& d : job.decals)
    if (d.x1_m > x0 && d.x0_m < x1 && d.y1_m > y0 && d.y0_m < y1) ++w.decals;
  return w;
}

VTSIM_PRODUCE_CLONES
void blend_rgba8(const std::uint8_t* const* layers, const std::uint16_t* const* weights, int n_layers, std::size_t texels,
                 std::uint8_t* out) {
  // Chunks of 64 texels: the accumulators (1 KiB) stay in L1 across the layers.
  constexpr std::size_t kChunk = 64;
  std::uint32_t acc[kChunk * 4];
  for (std::size_t t0 = 0; t0 < texels; t0 += kChunk) {
    const std::size_t n = std::min(kChunk, texels - t0);
    for (std::size_t i = 0; i < kChunk * 4; ++i) acc[i] = kWeightOne / 2;
    for (int l = 0; l < n_layers; ++l) {
      const std::uint8_t* px = layers[l] + t0 * 4;
      const std::uint16_t* w = weights[l] + t0;
      for (std::size_t t = 0; t < n; ++t)
        for (std::size_t c = 0; c < 4; ++c) acc[t * 4 + c] += static_cast<std::uint32_t>(w[t]) * px[t * 4 + c];
    }
    for (std::size_t i = 0; i < n * 4; ++i) out[t0 * 4 + i] = static_cast<std::uint8_t>(acc[i] >> kWeightBits);
  }
}

namespace {

// A position along one axis of level (side s, border nb): taps i0, i1 in brush texels (i1 may be s,
// the border) and the 8-bit fraction. Without a border the half-texel inset clamps to the edge
// texel instead of filtering across the wrap.
struct Tap {
  int i0, i1, f;
};
inline Tap tap_of(std::int64_t p, int s, int nb) {
  Tap t{static_cast<int>(p >> 32), static_cast<int>(p >> 32) + 1, static_cast<int>((p >> 24) & 255)};
  if (nb == 0 && t.i0 == s - 1) {  // p in [s-1, s): either q in [s-0.5, s) or the wrap of q in [0, 0.5)
    if (t.f < 128) t = {s - 1, s - 1, 0};
    else t = {0, 0, 0};
  }
  return t;
}

// 32.32 fixed position of frac(u) * s - 0.5, wrapped into [0, s).
inline std::int64_t fixed_pos(double u, int s) {
  double p = (u - std::floor(u)) * s - 0.5;
  if (p < 0) p += s;
  return static_cast<std::int64_t>(p * 4294967296.0) & ((static_cast<std::int64_t>(s) << 32) - 1);
}

}  // namespace

void sample_bilinear(const Atlas& atlas, int m, int b, double u, double v, bool inset, std::uint8_t out[4]) {
  const AtlasLevel& lv = atlas.levels.at(static_cast<std::size_t>(m));
  const int s = lv.brush_side;
  const auto axis = [&](double w) {
    if (inset || lv.border > 0) return tap_of(fixed_pos(w, s), s, inset ? lv.border : 1);
    // No inset, no border: the taps run past the cell into its neighbour (the bleeding of seed 004 §6).
    const std::int64_t p = fixed_pos(w, s);
    return Tap{static_cast<int>(p >> 32), static_cast<int>(p >> 32) + 1, static_cast<int>((p >> 24) & 255)};
  };
  const Tap tx = axis(u), ty = axis(v);
  const int cx0 = (b % atlas.cols) * lv.cell + lv.border, cy0 = (b / atlas.cols) * lv.cell + lv.border;
  const auto at = [&](int x, int y) {
    const int ax = std::clamp(cx0 + x, 0, lv.width - 1), ay = std::clamp(cy0 + y, 0, lv.height - 1);
    return &lv.rgba[(static_cast<std::size_t>(ay) * static_cast<std::size_t>(lv.width) + static_cast<std::size_t>(ax)) * 4];
  };
  const std::uint8_t *a = at(tx.i0, ty.i0), *bb = at(tx.i1, ty.i0), *c = at(tx.i0, ty.i1), *d = at(tx.i1, ty.i1);
  for (int k = 0; k < 4; ++k) {
    const int top = a[k] * (256 - tx.f) + bb[k] * tx.f, bot = c[k] * (256 - tx.f) + d[k] * tx.f;
    out[k] = static_cast<std::uint8_t>((top * (256 - ty.f) + bot * ty.f + 32768) >> 16);
  }
}

void Compositor::compose(const CompositeJob& job, std::uint8_t* out) {
  if (!job.atlas || job.atlas->levels.empty()) throw InputError("atlas", "no atlas given");
  if (job.layers.empty() || job.layers.size() > kMaxLayers)
    throw InputError("layers", fmt::format("{} layers: give 1 to {}", job.layers.size(), kMaxLayers));
  if (job.masks.size() * 4 < job.layers.size())
    throw InputError("masks", fmt::format("{} masks weight {} layers: need one mask per 4 layers", job.masks.size(), job.layers.size()));
  if (job.tile < 1 || job.border < 0 || !(job.m_per_texel > 0))
    throw InputError("tile", "tile >= 1, border >= 0 and m_per_texel > 0 required");
  for (const BrushLayer& l : job.layers)
    if (l.cell < 0 || l.cell >= job.atlas->brushes || !(l.period_m > 0))
      throw InputError("layers", fmt::format("cell {} (atlas has {}) period {} m: bad layer", l.cell, job.atlas->brushes, l.period_m));
  const Atlas& at = *job.atlas;
  const int n = job.tile + 2 * job.border;
  const std::size_t un = static_cast<std::size_t>(n);
  raw_.assign(kMaxLayers * un, 0.0f);
  w_.assign(kMaxLayers * un, 0);
  samp_.assign(kMaxLayers * un * 4, 0);
  const std::uint32_t act = active_layers(job);
  int ids[kMaxLayers];
  int na = 0;
  for (int l = 0; l < static_cast<int>(job.layers.size()); ++l)
    if (act & (1u << l)) ids[na++] = l;
  // Per layer, constant over the tile (a clipmap tile is seen straight down): level and step.
  int lvl[kMaxLayers];
  std::int64_t step[kMaxLayers];
  for (int k = 0; k < na; ++k) {
    const BrushLayer& bl = job.layers[static_cast<std::size_t>(ids[k])];
    lvl[k] = select_level(at, job.m_per_texel, bl.period_m);
    const int s = at.levels[static_cast<std::size_t>(lvl[k])].brush_side;
    step[k] = static_cast<std::int64_t>(std::llround(job.m_per_texel / bl.period_m * s * 4294967296.0)) & ((static_cast<std::int64_t>(s) << 32) - 1);
  }
  const std::uint8_t* lp[kMaxLayers];
  const std::uint16_t* wp[kMaxLayers];
  for (int k = 0; k < na; ++k) {
    lp[k] = &samp_[static_cast<std::size_t>(k) * un * 4];
    wp[k] = &w_[static_cast<std::size_t>(k) * un];
  }
  // The mask columns each output column reads (x0, x1, fraction), once per tile and mask: they do
  // not depend on the row or the layer.
  const std::size_t nm = job.masks.size();
  mx_.resize(nm * un * 2);
  mfx_.resize(nm * un);
  for (std::size_t mi = 0; mi < nm; ++mi) {
    const WeightMask& m = job.masks[mi];
    for (int i = 0; i < n; ++i) {
      const double wx = job.origin_x_m + (i - job.border + 0.5) * job.m_per_texel;
      const double mx = std::clamp((wx - m.origin_x_m) / m.m_per_texel - 0.5, 0.0, m.width - 1.0);
      const int x0 = static_cast<int>(mx);
      mx_[(mi * un + static_cast<std::size_t>(i)) * 2] = x0 * 4;
      mx_[(mi * un + static_cast<std::size_t>(i)) * 2 + 1] = std::min(x0 + 1, m.width - 1) * 4;
      mfx_[mi * un + static_cast<std::size_t>(i)] = static_cast<float>(mx - x0);
    }
  }
  for (int j = 0; j < n; ++j) {
    const double wy = job.origin_y_m + (j - job.border + 0.5) * job.m_per_texel;
    // Raw weights: bilinear in the masks, clamped at their edges.
    for (int k = 0; k < na; ++k) {
      const std::size_t mi = static_cast<std::size_t>(ids[k] / 4);
      const WeightMask& m = job.masks[mi];
      const int ch = ids[k] % 4;
      const double my = std::clamp((wy - m.origin_y_m) / m.m_per_texel - 0.5, 0.0, m.height - 1.0);
      const int y0 = static_cast<int>(my), y1 = std::min(y0 + 1, m.height - 1);
      const float fy = static_cast<float>(my - y0);
      const std::uint8_t* r0 = m.rgba + static_cast<std::size_t>(y0) * static_cast<std::size_t>(m.width) * 4 + ch;
      const std::uint8_t* r1 = m.rgba + static_cast<std::size_t>(y1) * static_cast<std::size_t>(m.width) * 4 + ch;
      float* raw = &raw_[static_cast<std::size_t>(k) * un];
      const int* mx = &mx_[mi * un * 2];
      const float* mfx = &mfx_[mi * un];
      for (int i = 0; i < n; ++i) {
        const int x0 = mx[2 * i], x1 = mx[2 * i + 1];
        const float fx = mfx[i];
        const float top = r0[x0] + (static_cast<float>(r0[x1]) - r0[x0]) * fx;
        const float bot = r1[x0] + (static_cast<float>(r1[x1]) - r1[x0]) * fx;
        raw[i] = top + (bot - top) * fy;
      }
    }
    // Normalise to kWeightOne; the rounding remainder goes to the heaviest layer; no weight at
    // all gives the first active layer everything.
    for (int i = 0; i < n; ++i) {
      float sum = 0;
      for (int k = 0; k < na; ++k) sum += raw_[static_cast<std::size_t>(k) * un + static_cast<std::size_t>(i)];
      int total = 0, heavy = 0;
      std::uint16_t best = 0;
      for (int k = 0; k < na; ++k) {
        const float r = raw_[static_cast<std::size_t>(k) * un + static_cast<std::size_t>(i)];
        const auto q = sum > 0 ? static_cast<std::uint16_t>(r * (static_cast<float>(kWeightOne) / sum) + 0.5f) : std::uint16_t{0};
        w_[static_cast<std::size_t>(k) * un + static_cast<std::size_t>(i)] = q;
        total += q;
        if (q > best) best = q, heavy = k;
      }
      w_[static_cast<std::size_t>(heavy) * un + static_cast<std::size_t>(i)] =
          static_cast<std::uint16_t>(w_[static_cast<std::size_t>(heavy) * un + static_cast<std::size_t>(i)] + (kWeightOne - total));
    }
    // Sample the layers with weight on this row.
    for (int k = 0; k < na; ++k) {
      const std::uint16_t* w = wp[k];
      if (std::all_of(w, w + n, [](std::uint16_t v) { return v == 0; })) continue;
      const BrushLayer& bl = job.layers[static_cast<std::size_t>(ids[k])];
      const AtlasLevel& lv = at.levels[static_cast<std::size_t>(lvl[k])];
      const int s = lv.brush_side;
      const std::int64_t mask = (static_cast<std::int64_t>(s) << 32) - 1;
      const Tap ty = tap_of(fixed_pos(wy / bl.period_m, s), s, lv.border);
      const int cx0 = (bl.cell % at.cols) * lv.cell + lv.border, cy0 = (bl.cell / at.cols) * lv.cell + lv.border;
      const std::uint8_t* row0 = &lv.rgba[(static_cast<std::size_t>(cy0 + ty.i0) * static_cast<std::size_t>(lv.width) + static_cast<std::size_t>(cx0)) * 4];
      const std::uint8_t* row1 = &lv.rgba[(static_cast<std::size_t>(cy0 + ty.i1) * static_cast<std::size_t>(lv.width) + static_cast<std::size_t>(cx0)) * 4];
      std::int64_t p = fixed_pos((job.origin_x_m + (0.5 - job.border) * job.m_per_texel) / bl.period_m, s);
      std::uint8_t* o = &samp_[static_cast<std::size_t>(k) * un * 4];
      const int fy = ty.f;
      for (int i = 0; i < n; ++i, p = (p + step[k]) & mask) {
        const Tap tx = tap_of(p, s, lv.border);
        const std::uint8_t *a = row0 + tx.i0 * 4, *b = row0 + tx.i1 * 4, *c = row1 + tx.i0 * 4, *d = row1 + tx.i1 * 4;
        for (int ch = 0; ch < 4; ++ch) {
          const int top = a[ch] * (256 - tx.f) + b[ch] * tx.f, bot = c[ch] * (256 - tx.f) + d[ch] * tx.f;
          o[i * 4 + ch] = static_cast<std::uint8_t>((top * (256 - fy) + bot * fy + 32768) >> 16);
        }
      }
    }
    blend_rgba8(lp, wp, na, un, out + static_cast<std::size_t>(j) * un * 4);
  }
}

void compose_exact(const CompositeJob& job, std::uint8_t* out) {
  const Atlas& at = *job.atlas;
  const int n = job.tile + 2 * job.border;
  const std::size_t nl = job.layers.size();
  const std::size_t first = static_cast<std::size_t>(std::countr_zero(active_layers(job)));  // no weight: all to it
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double wx = job.origin_x_m + (i - job.border + 0.5) * job.m_per_texel;
      const double wy = job.origin_y_m + (j - job.border + 0.5) * job.m_per_texel;
      std::array<double, kMaxLayers> raw{};
      double sum = 0;
      for (std::size_t l = 0; l < nl; ++l) {
        const WeightMask& m = job.masks[l / 4];
        const double mx = std::clamp((wx - m.origin_x_m) / m.m_per_texel - 0.5, 0.0, m.width - 1.0);
        const double my = std::clamp((wy - m.origin_y_m) / m.m_per_texel - 0.5, 0.0, m.height - 1.0);
        const int x0 = static_cast<int>(mx), y0 = static_cast<int>(my);
        const int x1 = std::min(x0 + 1, m.width - 1), y1 = std::min(y0 + 1, m.height - 1);
        const auto v = [&](int x, int y) { return static_cast<double>(m.rgba[(static_cast<std::size_t>(y) * static_cast<std::size_t>(m.width) + static_cast<std::size_t>(x)) * 4 + l % 4]); };
        const double fx = mx - x0, fy = my - y0;
        raw[l] = (v(x0, y0) * (1 - fx) + v(x1, y0) * fx) * (1 - fy) + (v(x0, y1) * (1 - fx) + v(x1, y1) * fx) * fy;
        sum += raw[l];
      }
      std::array<double, 4> c{};
      for (std::size_t l = 0; l < nl; ++l) {
        const double w = sum > 0 ? raw[l] / sum : (l == first ? 1.0 : 0.0);
        if (w == 0) continue;
        const BrushLayer& bl = job.layers[l];
        const AtlasLevel& lv = at.levels[static_cast<std::size_t>(select_level(at, job.m_per_texel, bl.period_m))];
        const int s = lv.brush_side;
        const auto axis = [&](double wv, int& i0, double& f) {
          double p = (wv / bl.period_m - std::floor(wv / bl.period_m)) * s - 0.5;
          if (p < 0) p += s;
          i0 = static_cast<int>(std::floor(p));
          f = p - i0;
        };
        int ix = 0, iy = 0;
        double fx = 0, fy = 0;
        axis(wx, ix, fx);
        axis(wy, iy, fy);
        const auto t = [&](int x, int y) { return lv.texel(at.cols, bl.cell, x % s, y % s); };
        for (int k = 0; k < 4; ++k)
          c[static_cast<std::size_t>(k)] += w * ((t(ix, iy)[k] * (1 - fx) + t(ix + 1, iy)[k] * fx) * (1 - fy) +
                                                  (t(ix, iy + 1)[k] * (1 - fx) + t(ix + 1, iy + 1)[k] * fx) * fy);
      }
      for (int k = 0; k < 4; ++k)
        out[(static_cast<std::size_t>(j) * static_cast<std::size_t>(n) + static_cast<std::size_t>(i)) * 4 + static_cast<std::size_t>(k)] =
            static_cast<std::uint8_t>(std::clamp(std::floor(c[static_cast<std::size_t>(k)] + 0.5), 0.0, 255.0));
    }
}

}  // namespace vtsim::produce
