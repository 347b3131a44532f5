#include "stream/produce/compositor.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <emmintrin.h>

#include "core/error.h"

// Two paths (ComposePath): the row kernels inlined into a function for baseline x86-64 (SSE2) and
// one with target("avx2"), chosen at run time (no ifunc: TSan crashes on an ifunc resolver at load,
// sim/view/simd.h, so VTSIM_NO_TARGET_CLONES keeps the generic path only). The AVX2 path does not
// enable FMA and this file is compiled with -ffp-contract=off (CMakeLists.txt), so the float
// weights are the same IEEE operations in the same order on both paths: the same bits.
#if defined(VTSIM_NO_TARGET_CLONES)
#define VTSIM_TARGET_AVX2
#else
#define VTSIM_TARGET_AVX2 __attribute__((target("avx2")))
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
    // Stop at the first texel that completes the channels this mask weights: a coarse level's tile
    // covers the whole mask (512² x 4 bytes), and scanning all of it cost ~1.7 ms a tile.
    std::uint32_t want = 0;
    for (std::size_t c = 0; c < 4; ++c)
      if (4 * i + c < job.layers.size()) want |= 1u << c;
    std::uint32_t found = 0;
    for (int y = my0; y <= my1 && found != want; ++y)
      for (int x = mx0; x <= mx1 && found != want; ++x)
        for (int c = 0; c < 4; ++c)
          if (m.rgba[(static_cast<std::size_t>(y) * static_cast<std::size_t>(m.width) + static_cast<std::size_t>(x)) * 4 + static_cast<std::size_t>(c)])
            found |= 1u << c;
    act |= (found & want) << (4 * i);
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
    if (decal_drawn(d, job.m_per_texel, x0, y0, x1, y1)) {
      ++w.decals;
      w.decal_texels += decal_span(d, job.m_per_texel, x0, y0, static_cast<int>(side), static_cast<int>(side)).texels();
    }
  return w;
}

DecalSpan decal_span(const Decal& d, double m_per_texel, double x0, double y0, int nx, int ny) {
  const double t = m_per_texel;
  // Clamped in double first: a decal far off the tile must not overflow the int conversion.
  const auto lo = [&](double v, int n) { return static_cast<int>(std::clamp(std::floor(v / t), 0.0, static_cast<double>(n))); };
  const auto hi = [&](double v, int n) { return static_cast<int>(std::clamp(std::ceil(v / t), 0.0, static_cast<double>(n))); };
  return DecalSpan{lo(d.x0_m - x0, nx), hi(d.x1_m - x0, nx), lo(d.y0_m - y0, ny), hi(d.y1_m - y0, ny)};
}

bool decal_drawn(const Decal& d, double m_per_texel, double x0, double y0, double x1, double y1) {
  return d.x1_m - d.x0_m >= m_per_texel && d.y1_m - d.y0_m >= m_per_texel && d.x1_m > x0 && d.x0_m < x1 && d.y1_m > y0 &&
         d.y0_m < y1;
}

void draw_decals(const CompositeJob& job, std::uint8_t* out) {
  if (job.decals.empty()) return;
  const int n = job.tile + 2 * job.border;
  const double t = job.m_per_texel;
  const double x0 = job.origin_x_m - job.border * t, y0 = job.origin_y_m - job.border * t;
  const double x1 = x0 + n * t, y1 = y0 + n * t;
  std::vector<double> cx(static_cast<std::size_t>(n)), cy(static_cast<std::size_t>(n));
  for (const Decal& d : job.decals) {
    if (!decal_drawn(d, t, x0, y0, x1, y1)) continue;
    // Coverage is separable for a rectangle: the overlap of each texel's column and row with it.
    const auto cover = [&](double a, double b, double o, std::vector<double>& c) {
      for (int i = 0; i < n; ++i) {
        const double lo = o + i * t, hi = lo + t;
        c[static_cast<std::size_t>(i)] = std::max(0.0, std::min(b, hi) - std::max(a, lo)) / t;
      }
    };
    cover(d.x0_m, d.x1_m, x0, cx);
    cover(d.y0_m, d.y1_m, y0, cy);
    const DecalSpan sp = decal_span(d, t, x0, y0, n, n);
    // Branch-free per texel: a = 0 leaves c as it was ((255 c + 127) / 255 = c). Coverage ≥ 0, so
    // truncating x + 0.5 rounds; v / 255 for v ≤ 65152 is exactly ((v + 1) + ((v + 1) >> 8)) >> 8.
    const auto div255 = [](std::uint32_t v) { return static_cast<std::uint8_t>(((v + 1) + ((v + 1) >> 8)) >> 8); };
    const std::uint32_t r = d.rgba[0], g = d.rgba[1], b = d.rgba[2];
    for (int j = sp.j0; j < sp.j1; ++j) {
      const double row_alpha = cy[static_cast<std::size_t>(j)] * d.rgba[3];
      std::uint8_t* row = out + static_cast<std::size_t>(j) * static_cast<std::size_t>(n) * 4;
      for (int i = sp.i0; i < sp.i1; ++i) {
        const std::uint32_t a = static_cast<std::uint32_t>(cx[static_cast<std::size_t>(i)] * row_alpha + 0.5), na = 255 - a;
        std::uint8_t* c = row + static_cast<std::size_t>(i) * 4;
        c[0] = div255(c[0] * na + r * a + 127);
        c[1] = div255(c[1] * na + g * a + 127);
        c[2] = div255(c[2] * na + b * a + 127);
        c[3] = div255(c[3] * na + 255 * a + 127);
      }
    }
  }
}

namespace {

// The blend, inlined into each path's row function (the body is compiled once per instruction set).
[[gnu::always_inline]] inline void blend_body(const std::uint8_t* const* layers, const std::uint16_t* const* weights, int n_layers,
                                              std::size_t texels, std::uint8_t* out) {
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

void blend_generic(const std::uint8_t* const* layers, const std::uint16_t* const* weights, int n_layers, std::size_t texels,
                   std::uint8_t* out) {
  blend_body(layers, weights, n_layers, texels, out);
}
VTSIM_TARGET_AVX2 void blend_avx2(const std::uint8_t* const* layers, const std::uint16_t* const* weights, int n_layers, std::size_t texels,
                                  std::uint8_t* out) {
  blend_body(layers, weights, n_layers, texels, out);
}

}  // namespace

bool compose_path_available(ComposePath path) {
  switch (path) {
    case ComposePath::kAuto:
    case ComposePath::kGeneric:
      return true;
    case ComposePath::kAvx2:
#if defined(VTSIM_NO_TARGET_CLONES)
      return false;
#else
      return __builtin_cpu_supports("avx2");
#endif
  }
  return false;
}

namespace {
// kAuto resolved once: the widest path this CPU runs.
ComposePath resolve(ComposePath path) {
  static const ComposePath best = compose_path_available(ComposePath::kAvx2) ? ComposePath::kAvx2 : ComposePath::kGeneric;
  return path == ComposePath::kAuto ? best : path;
}
}  // namespace

void blend_rgba8(const std::uint8_t* const* layers, const std::uint16_t* const* weights, int n_layers, std::size_t texels,
                 std::uint8_t* out) {
  if (resolve(ComposePath::kAuto) == ComposePath::kAvx2) blend_avx2(layers, weights, n_layers, texels, out);
  else blend_generic(layers, weights, n_layers, texels, out);
}

namespace {

void validate(const CompositeJob& job) {
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
}

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
    // No inset, no border: the taps run past the cell into its neighbour (the bleeding of crazii 2017 item 6).
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

namespace {

// The mask columns each output column reads (the byte offsets of mask texels x0 and x1, and the
// fraction between them), once per tile and mask: they depend on neither the row nor the layer.
void mask_columns(const CompositeJob& job, int n, std::vector<int>& mx_out, std::vector<float>& mfx_out) {
  const std::size_t un = static_cast<std::size_t>(n);
  const std::size_t nm = job.masks.size();
  mx_out.resize(nm * un * 2);
  mfx_out.resize(nm * un);
  for (std::size_t mi = 0; mi < nm; ++mi) {
    const WeightMask& m = job.masks[mi];
    for (int i = 0; i < n; ++i) {
      const double wx = job.origin_x_m + (i - job.border + 0.5) * job.m_per_texel;
      const double mx = std::clamp((wx - m.origin_x_m) / m.m_per_texel - 0.5, 0.0, m.width - 1.0);
      const int x0 = static_cast<int>(mx);
      mx_out[(mi * un + static_cast<std::size_t>(i)) * 2] = x0 * 4;
      mx_out[(mi * un + static_cast<std::size_t>(i)) * 2 + 1] = std::min(x0 + 1, m.width - 1) * 4;
      mfx_out[mi * un + static_cast<std::size_t>(i)] = static_cast<float>(mx - x0);
    }
  }
}

}  // namespace

// The per-texel loop before the row kernels (docs/produced.md, "The compositor"): kept as the
// bit-exact reference of compose's every path.
void compose_reference(const CompositeJob& job, std::uint8_t* out) {
  validate(job);
  std::vector<float> raw_;
  std::vector<std::uint16_t> w_;
  std::vector<std::uint8_t> samp_;
  std::vector<int> mx_;
  std::vector<float> mfx_;
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
  mask_columns(job, n, mx_, mfx_);
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
  draw_decals(job, out);
}

namespace {

// One tile's state for the row kernels, prepared once per tile by Compositor::compose.
struct TileRows {
  int n = 0;           // row length, texels
  std::size_t un = 0;
  int na = 0;          // active layers
  double origin_y_m = 0, m_per_texel = 0;
  int border = 0;
  const WeightMask* masks = nullptr;
  int nm = 0;
  const int* mx = nullptr;     // per mask, n pairs: byte offsets of mask texels x0, x1 in a row
  const float* mfx = nullptr;  // per mask, n fractions
  // Per mask, two cached rows of horizontally interpolated weights (4 channels x n floats each),
  // for the mask rows in cache_y: a mask magnified over the tile serves many output rows per row.
  float* hrow = nullptr;
  int* cache_y = nullptr;
  std::uint32_t mask_ch[4] = {};  // per mask, the channels some active layer reads
  // Per active layer k.
  int mi[kMaxLayers] = {}, ch[kMaxLayers] = {};
  double period[kMaxLayers] = {};
  int side[kMaxLayers] = {}, nb[kMaxLayers] = {};
  std::size_t row_bytes[kMaxLayers] = {};          // atlas level row, bytes
  const std::uint8_t* brush0[kMaxLayers] = {};     // brush texel (0, 0) of the layer's level
  const int* tx = nullptr;                         // per layer, n tap columns i0
  const std::uint32_t* twf = nullptr;              // per layer, n words (f << 16) | (256 - f)
  const int* runs = nullptr;                       // per layer runs of needed columns [a, b] ...
  const int* run_begin = nullptr;                  // ... layer k's are runs[2 run_begin[k] .. 2 run_begin[k+1])
  // Row scratch.
  float* raw = nullptr;           // kMaxLayers x n
  float* inv = nullptr;           // n
  std::uint16_t* w = nullptr;     // kMaxLayers x n
  std::uint16_t* best = nullptr;  // n
  std::uint16_t* total = nullptr; // n
  std::uint8_t* heavy = nullptr;  // n
  std::uint16_t* vrow = nullptr;  // (largest side + 1) x 4: the vertical pass of one layer
  std::int32_t* acc = nullptr;    // n x 4: the blend's sums
};

// Mask row r (RGBA8) interpolated horizontally at the tile's columns, channels in `chans`:
// out[c * n + i] = r[x0] + (r[x1] - r[x0]) * fx, the reference's float expression.
[[gnu::always_inline]] inline void mask_hrow(const std::uint8_t* r, const int* mx, const float* mfx, int n, std::uint32_t chans,
                                             float* out) {
  const std::size_t un = static_cast<std::size_t>(n);
  for (int c = 0; c < 4; ++c) {
    if (!(chans & (1u << c))) continue;
    float* o = out + static_cast<std::size_t>(c) * un;
    for (int i = 0; i < n; ++i) {
      const float a = r[mx[2 * i] + c], b = r[mx[2 * i + 1] + c];
      o[i] = a + (b - a) * mfx[i];
    }
  }
}

// The cached horizontal row of mask mi for mask row y, computing it into a slot `keep` does not hold.
[[gnu::always_inline]] inline const float* mask_row(TileRows& t, int mi, int y, int keep) {
  const std::size_t slot = static_cast<std::size_t>(mi) * 2;
  const std::size_t stride = 4 * t.un;
  for (std::size_t s = 0; s < 2; ++s)
    if (t.cache_y[slot + s] == y) return t.hrow + (slot + s) * stride;
  const std::size_t s = t.cache_y[slot] == keep ? 1 : 0;
  const WeightMask& m = t.masks[mi];
  mask_hrow(m.rgba + static_cast<std::size_t>(y) * static_cast<std::size_t>(m.width) * 4, t.mx + static_cast<std::size_t>(mi) * t.un * 2,
            t.mfx + static_cast<std::size_t>(mi) * t.un, t.n, t.mask_ch[mi], t.hrow + (slot + s) * stride);
  t.cache_y[slot + s] = y;
  return t.hrow + (slot + s) * stride;
}

// Horizontal pass of one layer's row, blended as it goes: the sample c = (X + 2^15) >> 16 with
// X = (256 - f) v[i0] + f v[i0 + 1], v the vertical pass stored as v - 2^15 (int16), so one pmaddwd
// gives X - 2^23 per channel; then acc += w c, c < 256 and w <= 2^14 as int16 pairs (c, 0) . (w, 0),
// a second pmaddwd. The sum is blend_rgba8's exact integer (the sampled bytes never stored).
[[gnu::always_inline]] inline void sample_blend(const std::uint16_t* vrow, const int* tx, const std::uint32_t* twf, const std::uint16_t* w, int n,
                                                std::int32_t* acc) {
  const __m128i bias = _mm_set1_epi32((1 << 23) + (1 << 15));
  for (int i = 0; i < n; ++i) {
    __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(vrow + 4 * static_cast<std::size_t>(tx[i])));
    x = _mm_unpacklo_epi16(x, _mm_srli_si128(x, 8));  // (v0 c, v1 c) pairs
    x = _mm_madd_epi16(x, _mm_set1_epi32(static_cast<int>(twf[i])));
    x = _mm_srai_epi32(_mm_add_epi32(x, bias), 16);
    x = _mm_madd_epi16(x, _mm_set1_epi32(w[i]));
    __m128i* a = reinterpret_cast<__m128i*>(acc + 4 * static_cast<std::size_t>(i));
    _mm_storeu_si128(a, _mm_add_epi32(_mm_loadu_si128(a), x));
  }
}

// out = acc >> 14 as bytes (acc < 2^22: 255 . 2^14 + 2^13).
[[gnu::always_inline]] inline void store_row(const std::int32_t* acc, int n, std::uint8_t* o) {
  const auto at = [&](int i) { return _mm_srli_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(acc + 4 * static_cast<std::size_t>(i))), kWeightBits); };
  int i = 0;
  for (; i + 4 <= n; i += 4)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(o + 4 * static_cast<std::size_t>(i)),
                     _mm_packus_epi16(_mm_packs_epi32(at(i), at(i + 1)), _mm_packs_epi32(at(i + 2), at(i + 3))));
  for (; i < n; ++i) {
    const int v = _mm_cvtsi128_si32(_mm_packus_epi16(_mm_packs_epi32(at(i), at(i)), _mm_setzero_si128()));
    std::memcpy(o + 4 * static_cast<std::size_t>(i), &v, 4);
  }
}

// Rows [j0, j1) of the tile (docs/produced.md, "The compositor": the same integers and floats as
// compose_reference, reorganised: weights in rows of texels, the brush taps' columns per tile, the
// bilinear sample split into a vertical pass over the brush columns the row reads and a horizontal
// pmaddwd per texel; (256-fy)((256-fx)a + fx b) + fy((256-fx)c + fx d) regroups exactly).
[[gnu::always_inline]] inline void rows_body(TileRows& t, int j0, int j1, std::uint8_t* out) {
  const int n = t.n, na = t.na;
  const std::size_t un = t.un;
  for (int j = j0; j < j1; ++j) {
    const double wy = t.origin_y_m + (j - t.border + 0.5) * t.m_per_texel;  // the reference's expression
    // Raw weights: bilinear in the masks (clamped at their edges), horizontal rows cached per mask row.
    for (int k = 0; k < na; ++k) {
      const WeightMask& m = t.masks[t.mi[k]];
      const double my = std::clamp((wy - m.origin_y_m) / m.m_per_texel - 0.5, 0.0, m.height - 1.0);
      const int y0 = static_cast<int>(my), y1 = std::min(y0 + 1, m.height - 1);
      const float fy = static_cast<float>(my - y0);
      const float* top = mask_row(t, t.mi[k], y0, y1) + static_cast<std::size_t>(t.ch[k]) * un;
      const float* bot = mask_row(t, t.mi[k], y1, y0) + static_cast<std::size_t>(t.ch[k]) * un;
      float* __restrict raw = t.raw + static_cast<std::size_t>(k) * un;
      for (int i = 0; i < n; ++i) raw[i] = top[i] + (bot[i] - top[i]) * fy;
    }
    // Normalise to kWeightOne; the remainder goes to the (first) heaviest layer. Raw weights are
    // >= 0, so a zero sum means all zero: every q is 0 and layer 0 (the first active) takes all.
    // Local restrict pointers: a store through heavy (bytes) could otherwise alias t's fields.
    float* __restrict inv = t.inv;
    std::uint16_t* __restrict best = t.best;
    std::uint16_t* __restrict total = t.total;
    std::uint8_t* __restrict heavy = t.heavy;
    for (int i = 0; i < n; ++i) inv[i] = 0.0f;
    for (int k = 0; k < na; ++k) {
      const float* __restrict raw = t.raw + static_cast<std::size_t>(k) * un;
      for (int i = 0; i < n; ++i) inv[i] += raw[i];
    }
    // A zero sum divides 1 instead (its weights are all 0 whatever the scale); sum + 0 is the sum
    // exactly. Tested on the bits: a float comparison keeps the loop from vectorising
    // (-ftrapping-math). A sum of raw weights >= 0 is +0 only when zero.
    for (int i = 0; i < n; ++i) {
      std::uint32_t bits;
      std::memcpy(&bits, &inv[i], 4);
      inv[i] = static_cast<float>(kWeightOne) / (inv[i] + static_cast<float>(bits == 0));
    }
    for (int i = 0; i < n; ++i) best[i] = 0, total[i] = 0, heavy[i] = 0;
    for (int k = 0; k < na; ++k) {
      const float* __restrict raw = t.raw + static_cast<std::size_t>(k) * un;
      std::uint16_t* __restrict w = t.w + static_cast<std::size_t>(k) * un;
      for (int i = 0; i < n; ++i) {
        const auto q = static_cast<std::uint16_t>(static_cast<int>(raw[i] * inv[i] + 0.5f));
        w[i] = q;
        total[i] = static_cast<std::uint16_t>(total[i] + q);
        const bool more = q > best[i];
        best[i] = more ? q : best[i];
        heavy[i] = more ? static_cast<std::uint8_t>(k) : heavy[i];
      }
    }
    for (int k = 0; k < na; ++k) {
      std::uint16_t* __restrict w = t.w + static_cast<std::size_t>(k) * un;
      const auto kk = static_cast<std::uint8_t>(k);
      for (int i = 0; i < n; ++i) {
        const auto sel = static_cast<std::uint16_t>(-static_cast<int>(heavy[i] == kk));  // all ones on the heaviest layer
        w[i] = static_cast<std::uint16_t>(w[i] + (sel & static_cast<std::uint16_t>(kWeightOne - total[i])));
      }
    }
    // Sample and blend the layers with weight on this row (a layer of weight 0 adds 0).
    for (std::size_t q = 0; q < 4 * un; ++q) t.acc[q] = kWeightOne / 2;
    for (int k = 0; k < na; ++k) {
      const std::uint16_t* w = t.w + static_cast<std::size_t>(k) * un;
      if (std::all_of(w, w + n, [](std::uint16_t v) { return v == 0; })) continue;
      const int s = t.side[k], nb = t.nb[k];
      const Tap ty = tap_of(fixed_pos(wy / t.period[k], s), s, nb);
      const std::uint8_t* r0 = t.brush0[k] + static_cast<std::size_t>(ty.i0) * t.row_bytes[k];
      const std::uint8_t* r1 = t.brush0[k] + static_cast<std::size_t>(ty.i1) * t.row_bytes[k];
      const int wa = 256 - ty.f, wb = ty.f;
      // Vertical pass over the runs of brush columns the row's taps read, and each run's right
      // neighbour (column s is the border; without a border its tap weight is 0, so a copy).
      for (int r = t.run_begin[k]; r < t.run_begin[k + 1]; ++r) {
        const int a = t.runs[2 * r], b = std::min(t.runs[2 * r + 1] + 1, nb > 0 ? s : s - 1);
        const std::size_t lo = static_cast<std::size_t>(a) * 4, hi = static_cast<std::size_t>(b + 1) * 4;
        std::uint16_t* __restrict v = t.vrow;
        for (std::size_t q = lo; q < hi; ++q) v[q] = static_cast<std::uint16_t>((r0[q] * wa + r1[q] * wb) ^ 0x8000);
        if (b < t.runs[2 * r + 1] + 1) std::memcpy(v + hi, v + hi - 4, 4 * sizeof(std::uint16_t));
      }
      sample_blend(t.vrow, t.tx + static_cast<std::size_t>(k) * un, t.twf + static_cast<std::size_t>(k) * un, w, n, t.acc);
    }
    store_row(t.acc, n, out + static_cast<std::size_t>(j) * un * 4);
  }
}

void rows_generic(TileRows& t, int j0, int j1, std::uint8_t* out) { rows_body(t, j0, j1, out); }
VTSIM_TARGET_AVX2 void rows_avx2(TileRows& t, int j0, int j1, std::uint8_t* out) { rows_body(t, j0, j1, out); }

}  // namespace

void Compositor::compose(const CompositeJob& job, std::uint8_t* out, ComposePath path) {
  validate(job);
  const Atlas& at = *job.atlas;
  const int n = job.tile + 2 * job.border;
  const std::size_t un = static_cast<std::size_t>(n);
  const std::uint32_t act = active_layers(job);
  int ids[kMaxLayers];
  int na = 0;
  for (int l = 0; l < static_cast<int>(job.layers.size()); ++l)
    if (act & (1u << l)) ids[na++] = l;
  TileRows t;
  t.n = n;
  t.un = un;
  t.na = na;
  t.origin_y_m = job.origin_y_m;
  t.border = job.border;
  t.m_per_texel = job.m_per_texel;
  t.masks = job.masks.data();
  t.nm = static_cast<int>(job.masks.size());
  const std::size_t nm = job.masks.size();
  mask_columns(job, n, mx_, mfx_);
  t.mx = mx_.data();
  t.mfx = mfx_.data();
  hrow_.resize(nm * 2 * 4 * un);
  cache_y_.assign(nm * 2, -1);
  t.hrow = hrow_.data();
  t.cache_y = cache_y_.data();
  // Per layer, constant over the tile (a clipmap tile is seen straight down): level, step, and the
  // tap column and fraction of every output column (the same for every row).
  tx_.resize(static_cast<std::size_t>(na) * un);
  twf_.resize(static_cast<std::size_t>(na) * un);
  runs_.clear();
  int run_begin[kMaxLayers + 1] = {};
  int max_side = 1;
  for (int k = 0; k < na; ++k) {
    const BrushLayer& bl = job.layers[static_cast<std::size_t>(ids[k])];
    const int mi = ids[k] / 4;
    t.mi[k] = mi;
    t.ch[k] = ids[k] % 4;
    t.mask_ch[mi] |= 1u << t.ch[k];  // mi < 4: ids[k] < kMaxLayers
    const AtlasLevel& lv = at.levels[static_cast<std::size_t>(select_level(at, job.m_per_texel, bl.period_m))];
    const int s = lv.brush_side;
    max_side = std::max(max_side, s);
    t.period[k] = bl.period_m;
    t.side[k] = s;
    t.nb[k] = lv.border;
    t.row_bytes[k] = static_cast<std::size_t>(lv.width) * 4;
    const int cx0 = (bl.cell % at.cols) * lv.cell + lv.border, cy0 = (bl.cell / at.cols) * lv.cell + lv.border;
    t.brush0[k] = &lv.rgba[(static_cast<std::size_t>(cy0) * static_cast<std::size_t>(lv.width) + static_cast<std::size_t>(cx0)) * 4];
    const std::int64_t mask = (static_cast<std::int64_t>(s) << 32) - 1;
    const std::int64_t step = static_cast<std::int64_t>(std::llround(job.m_per_texel / bl.period_m * s * 4294967296.0)) & mask;
    std::int64_t p = fixed_pos((job.origin_x_m + (0.5 - job.border) * job.m_per_texel) / bl.period_m, s);
    need_.assign(static_cast<std::size_t>(s), 0);
    for (int i = 0; i < n; ++i, p = (p + step) & mask) {
      const Tap tx = tap_of(p, s, lv.border);  // i1 = i0 + 1, or f = 0 (no border)
      tx_[static_cast<std::size_t>(k) * un + static_cast<std::size_t>(i)] = tx.i0;
      twf_[static_cast<std::size_t>(k) * un + static_cast<std::size_t>(i)] = (static_cast<std::uint32_t>(tx.f) << 16) | static_cast<std::uint32_t>(256 - tx.f);
      need_[static_cast<std::size_t>(tx.i0)] = 1;
    }
    // Runs of needed columns; gaps under 8 columns are cheaper to fill than to skip.
    run_begin[k] = static_cast<int>(runs_.size() / 2);
    for (int c = 0; c < s;) {
      if (!need_[static_cast<std::size_t>(c)]) {
        ++c;
        continue;
      }
      int e = c, gap = 0;
      for (int q = c + 1; q < s && gap < 8; ++q) {
        if (need_[static_cast<std::size_t>(q)]) e = q, gap = 0;
        else ++gap;
      }
      runs_.push_back(c);
      runs_.push_back(e);
      c = e + 1;
    }
    run_begin[k + 1] = static_cast<int>(runs_.size() / 2);
  }
  t.tx = tx_.data();
  t.twf = twf_.data();
  t.runs = runs_.data();
  t.run_begin = run_begin;
  raw_.resize(kMaxLayers * un);
  inv_.resize(un);
  w_.assign(kMaxLayers * un, 0);
  best_.resize(un);
  total_.resize(un);
  heavy_.resize(un);
  vrow_.resize((static_cast<std::size_t>(max_side) + 1) * 4);
  acc_.resize(un * 4);
  t.raw = raw_.data();
  t.inv = inv_.data();
  t.w = w_.data();
  t.best = best_.data();
  t.total = total_.data();
  t.heavy = heavy_.data();
  t.vrow = vrow_.data();
  t.acc = acc_.data();
  if (resolve(path) == ComposePath::kAvx2) rows_avx2(t, 0, n, out);
  else rows_generic(t, 0, n, out);
  draw_decals(job, out);
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
  draw_decals(job, out);
}

}  // namespace vtsim::produce
