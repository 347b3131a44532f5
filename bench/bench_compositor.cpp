// The compositor (src/stream/produce/compositor.h) against OpenImageIO's ImageBufAlgo doing the same
// work on the same tiles, side by side in one run, one thread each (issue 27: >= 2x OpenImageIO's
// texels per second per core). docs/produced.md, "The compositor against OpenImageIO".
//
// - blend_N: the blend step alone. N layers of already-sampled RGBA8 rows and per-texel weights
//   normalised to 2^14: ours blend_rgba8 row by row; OpenImageIO mul + (N - 1) mad of the uint8
//   layers by float weight images (w / 2^14, exact in float), then the float result to uint8
//   (ImageBuf::get_pixels, round to nearest).
// - compose_N: the whole tile (weights from RGBA8 masks, sampling the brushes, blend): ours
//   Compositor::compose; OpenImageIO warp of each mask to the tile (triangle filter, clamped),
//   channel_sum + div to normalise, warp of each brush level (triangle filter, periodic wrap), mad
//   into a float tile, to uint8. The masks are procedural (stream/produce/masks.h) from an fBm
//   heightfield (sim/view/scene_heightfield.h), N height bands with soft edges.
// Outputs are compared texel by texel; the largest difference per channel is printed and written
// in the case's params. Mtexels/s = the op/s column / 10^6 (an op is one output texel).
//   build/bench/bench_compositor [--quick] [--reps N] [--json FILE] [--filter compose]
#include <OpenImageIO/Imath.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "harness.h"
#include "sim/view/scene_heightfield.h"
#include "stream/produce/atlas.h"
#include "stream/produce/compositor.h"
#include "stream/produce/masks.h"

namespace {

namespace OIIO = OIIO_NAMESPACE;
namespace vb = vtsim::bench;
using namespace vtsim::produce;

constexpr int kTile = 256, kBorder = 4, kN = kTile + 2 * kBorder;
constexpr std::size_t kTexels = static_cast<std::size_t>(kN) * kN;

std::uint64_t mix64(std::uint64_t x) {  // splitmix64's finaliser: deterministic inputs
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Brush b: smooth stripes and noise, so bilinear taps differ (a flat brush would hide sampling).
Rgba8 bench_brush(int s, int b) {
  Rgba8 im;
  im.width = im.height = s;
  im.texels.resize(static_cast<std::size_t>(s) * s * 4);
  const double tau = 6.283185307179586;
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x)
      for (int c = 0; c < 4; ++c) {
        const double v = 128 + 70 * std::sin(tau * (x * (1 + b % 3) + y * (c + 1)) / s) +
                         static_cast<double>(mix64(static_cast<std::uint64_t>(((b * 4 + c) * s + y) * s + x)) % 41) - 20;
        im.texels[(static_cast<std::size_t>(y) * s + x) * 4 + c] = static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
      }
  return im;
}

struct Diff {
  std::array<int, 4> max_abs{};
  std::size_t texels_off = 0;
};
Diff compare(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  Diff d;
  for (std::size_t t = 0; t < a.size() / 4; ++t) {
    bool off = false;
    for (int c = 0; c < 4; ++c) {
      const int e = std::abs(a[t * 4 + c] - b[t * 4 + c]);
      d.max_abs[static_cast<std::size_t>(c)] = std::max(d.max_abs[static_cast<std::size_t>(c)], e);
      off |= e != 0;
    }
    d.texels_off += off;
  }
  return d;
}
nlohmann::json diff_json(const Diff& d) {
  return {{"max_abs_diff_rgba", {d.max_abs[0], d.max_abs[1], d.max_abs[2], d.max_abs[3]}}, {"texels_differing", d.texels_off}};
}
void print_diff(const std::string& name, const Diff& d) {
  std::printf("  %s: max |ours - oiio| per channel R %d G %d B %d A %d; %zu of %zu texels differ\n", name.c_str(), d.max_abs[0],
              d.max_abs[1], d.max_abs[2], d.max_abs[3], d.texels_off, kTexels);
}
void print_rates(const vb::Result* r, const char* ref = "OpenImageIO") {
  if (r)
    std::printf("  %s: ours %.1f Mtexels/s, %s %.1f Mtexels/s, ratio %.2fx\n", r->spec.name.c_str(), r->ours.median / 1e6, ref,
                r->ref.median / 1e6, r->ratio);
}

OIIO::ImageSpec rgba_spec(int w, int h, OIIO::TypeDesc t) { return OIIO::ImageSpec(w, h, 4, t); }

// M (row vector, src -> dst) for dst = (src - b) / a on both axes.
Imath::M33f inverse_affine(double a, double bx, double by) {
  const float ia = static_cast<float>(1.0 / a);
  return Imath::M33f(ia, 0, 0, 0, ia, 0, static_cast<float>(-bx / a), static_cast<float>(-by / a), 1);
}

}  // namespace

int main(int argc, char** argv) {
  vb::Harness h("compositor", argc, argv);
  OIIO::attribute("threads", 1);
  const int reps_work = h.pick(8, 4);  // tiles per repetition, so a repetition lasts >= 1 ms
  h.param("tile", {{"payload", kTile}, {"border", kBorder}, {"texels", kTexels}});
  h.param("tiles_per_rep", reps_work);
  h.param("threads", 1);
  const OIIO::ROI roi(0, kN, 0, kN, 0, 1, 0, 4);

  // --- blend step ---------------------------------------------------------------------------
  for (int n : {1, 4, 8, 16}) {
    std::vector<std::vector<std::uint8_t>> layer(static_cast<std::size_t>(n), std::vector<std::uint8_t>(kTexels * 4));
    std::vector<std::vector<std::uint16_t>> weight(static_cast<std::size_t>(n), std::vector<std::uint16_t>(kTexels));
    for (int l = 0; l < n; ++l)
      for (std::size_t i = 0; i < kTexels * 4; ++i) layer[static_cast<std::size_t>(l)][i] = static_cast<std::uint8_t>(mix64(i * 17 + static_cast<std::size_t>(l)) & 255);
    for (std::size_t t = 0; t < kTexels; ++t) {  // raw weights normalised to 2^14, remainder to the heaviest
      std::array<std::uint32_t, kMaxLayers> raw{};
      std::uint32_t sum = 0;
      for (int l = 0; l < n; ++l) sum += raw[static_cast<std::size_t>(l)] = static_cast<std::uint32_t>(mix64(t * 31 + static_cast<std::size_t>(l) + 7) % 256) + 1;
      int total = 0, heavy = 0;
      for (int l = 0; l < n; ++l) {
        const int q = static_cast<int>((raw[static_cast<std::size_t>(l)] * static_cast<std::uint32_t>(kWeightOne) + sum / 2) / sum);
        weight[static_cast<std::size_t>(l)][t] = static_cast<std::uint16_t>(q);
        total += q;
        if (q > weight[static_cast<std::size_t>(heavy)][t]) heavy = l;
      }
      weight[static_cast<std::size_t>(heavy)][t] = static_cast<std::uint16_t>(weight[static_cast<std::size_t>(heavy)][t] + kWeightOne - total);
    }
    // OpenImageIO's view: uint8 layer images over the same bytes, float weights w / 2^14 (exact).
    std::vector<OIIO::ImageBuf> lbuf, wbuf;
    for (int l = 0; l < n; ++l) {
      lbuf.emplace_back(rgba_spec(kN, kN, OIIO::TypeDesc::UINT8), layer[static_cast<std::size_t>(l)].data());
      OIIO::ImageBuf w(rgba_spec(kN, kN, OIIO::TypeDesc::FLOAT));
      std::vector<float> wf(kTexels * 4);
      for (std::size_t t = 0; t < kTexels; ++t)
        for (int c = 0; c < 4; ++c) wf[t * 4 + static_cast<std::size_t>(c)] = weight[static_cast<std::size_t>(l)][t] / static_cast<float>(kWeightOne);
      w.set_pixels(roi, OIIO::TypeDesc::FLOAT, wf.data());
      wbuf.push_back(std::move(w));
    }
    std::vector<std::uint8_t> ours(kTexels * 4), theirs(kTexels * 4);
    OIIO::ImageBuf acc(rgba_spec(kN, kN, OIIO::TypeDesc::FLOAT));
    const auto run_ours = [&] {
      const std::uint8_t* lp[kMaxLayers];
      const std::uint16_t* wp[kMaxLayers];
      for (int k = 0; k < reps_work; ++k)
        for (int j = 0; j < kN; ++j) {  // row by row, as compose calls it
          const std::size_t off = static_cast<std::size_t>(j) * kN;
          for (int l = 0; l < n; ++l) {
            lp[l] = layer[static_cast<std::size_t>(l)].data() + off * 4;
            wp[l] = weight[static_cast<std::size_t>(l)].data() + off;
          }
          blend_rgba8(lp, wp, n, kN, ours.data() + off * 4);
        }
      vb::do_not_optimize(ours.data());
    };
    const auto run_oiio = [&] {
      for (int k = 0; k < reps_work; ++k) {
        OIIO::ImageBufAlgo::mul(acc, lbuf[0], wbuf[0], roi, 1);
        for (int l = 1; l < n; ++l) OIIO::ImageBufAlgo::mad(acc, lbuf[static_cast<std::size_t>(l)], wbuf[static_cast<std::size_t>(l)], acc, roi, 1);
        acc.get_pixels(roi, OIIO::TypeDesc::UINT8, theirs.data());
      }
      vb::do_not_optimize(theirs.data());
    };
    run_ours();
    run_oiio();
    const Diff d = compare(ours, theirs);
    const std::string name = "blend_" + std::to_string(n);
    nlohmann::json params = {{"layers", n}, {"reference", "ImageBufAlgo mul + mad, float, to uint8"}};
    params.update(diff_json(d));
    print_diff(name, d);
    print_rates(h.compare({.name = name, .metric = vb::Metric::kOpsPerS, .work = static_cast<double>(kTexels) * reps_work, .params = params, .target_ratio = 2.0},
                          {"blend_rgba8", {}, run_ours}, {"oiio_mad", {}, run_oiio}));
  }

  // --- whole compose ------------------------------------------------------------------------
  constexpr int kBrushSide = 256;
  std::vector<Rgba8> brushes;
  for (int b = 0; b < kMaxLayers; ++b) brushes.push_back(bench_brush(kBrushSide, b));
  const Atlas atlas = build_atlas(brushes, {}, {.cols = 4, .border = 4});
  // Heightfield: 257 x 257 posts 0.5 m apart, fBm hills of +-8 m; the tile: 256 texels of 1/32 m
  // (8 m) at (40, 40) m; masks 0.5 m a texel over the 128 m square (a sector's mask resolution
  // scaled down).
  const vtsim::Heightfield hf = vtsim::generate_heightfield(257, 0.5, 8.0, 0.0, 27, 0.0, 0.0);
  const HeightGrid grid{hf.nx, hf.ny, hf.spacing_m, hf.x0_m, hf.y0_m, hf.z_m.data()};
  const double mpt = 1.0 / 32, ox = 40.0, oy = 40.0, mask_mpt = 0.5;
  double hlo = 1e300, hhi = -1e300;  // the tile's height range: the bands split it
  for (int j = -8; j <= 8 * 32 + 8; j += 4)
    for (int i = -8; i <= 8 * 32 + 8; i += 4) {
      const double z = grid_height(grid, ox + i * mpt, oy + j * mpt);
      hlo = std::min(hlo, z), hhi = std::max(hhi, z);
    }
  h.param("compose", {{"brush_side", kBrushSide}, {"atlas_border", 4}, {"m_per_texel", mpt}, {"mask_m_per_texel", mask_mpt},
                      {"tile_height_range_m", {hlo, hhi}}, {"heightfield", "generate_heightfield(257, 0.5 m, 8 m, seed 27)"}});
  for (int n : {1, 4, 8, 16}) {
    std::vector<LayerRule> rules(static_cast<std::size_t>(n));
    const double band = (hhi - hlo) / n;
    for (int l = 0; l < n; ++l) {  // band l of the tile's heights, fading over two bands either side
      LayerRule& r = rules[static_cast<std::size_t>(l)];
      r.height_lo_m = l == 0 ? -1e9 : hlo + band * l;
      r.height_hi_m = l == n - 1 ? 1e9 : hlo + band * (l + 1);
      r.height_soft_m = 2 * band;
    }
    const ProceduralMasks pm = procedural_masks(grid, rules, 256, 256, 0.0, 0.0, mask_mpt);
    std::vector<WeightMask> masks;
    for (std::size_t i = 0; i < pm.rgba.size(); ++i) masks.push_back(pm.mask(i));
    std::vector<BrushLayer> layers;
    for (int l = 0; l < n; ++l) layers.push_back({l, 3.0 + 0.25 * l});  // levels 1 and 0, steps 0.67..1.33 texels
    CompositeJob job;
    job.atlas = &atlas;
    job.layers = layers;
    job.masks = masks;
    job.origin_x_m = ox;
    job.origin_y_m = oy;
    job.m_per_texel = mpt;
    job.tile = kTile;
    job.border = kBorder;
    const vtsim::ProduceWork work = count_work(job);
    // OpenImageIO's inputs: the masks as uint8 images, each layer's brush level as its own image.
    std::vector<OIIO::ImageBuf> mbuf, bbuf;
    for (std::size_t i = 0; i < pm.rgba.size(); ++i)
      mbuf.emplace_back(rgba_spec(pm.width, pm.height, OIIO::TypeDesc::UINT8), const_cast<std::uint8_t*>(pm.rgba[i].data()));
    std::vector<Imath::M33f> bm;
    for (int l = 0; l < n; ++l) {
      const int lv = select_level(atlas, mpt, layers[static_cast<std::size_t>(l)].period_m);
      const AtlasLevel& al = atlas.levels[static_cast<std::size_t>(lv)];
      const int s = al.brush_side;
      OIIO::ImageBuf b(rgba_spec(s, s, OIIO::TypeDesc::UINT8));
      std::vector<std::uint8_t> px(static_cast<std::size_t>(s) * s * 4);
      for (int y = 0; y < s; ++y) std::copy_n(al.texel(atlas.cols, l, 0, y), s * 4, &px[static_cast<std::size_t>(y) * s * 4]);
      b.set_pixels(OIIO::ROI(0, s, 0, s, 0, 1, 0, 4), OIIO::TypeDesc::UINT8, px.data());
      bbuf.push_back(std::move(b));
      // brush texel coordinate (centres at k + 0.5) = world / period * s; world = o + (dst - B) mpt.
      const double a = mpt / layers[static_cast<std::size_t>(l)].period_m * s;
      bm.push_back(inverse_affine(a, (ox - kBorder * mpt) / layers[static_cast<std::size_t>(l)].period_m * s,
                                  (oy - kBorder * mpt) / layers[static_cast<std::size_t>(l)].period_m * s));
    }
    const Imath::M33f mm = inverse_affine(mpt / mask_mpt, (ox - kBorder * mpt) / mask_mpt, (oy - kBorder * mpt) / mask_mpt);
    std::vector<std::uint8_t> ours(kTexels * 4), theirs(kTexels * 4);
    Compositor comp;
    std::vector<OIIO::ImageBuf> mw(mbuf.size());
    OIIO::ImageBuf sum, part, w1, w4, samp, acc;
    const OIIO::ROI roi1(0, kN, 0, kN, 0, 1, 0, 1);
    const auto run_ours = [&] {
      for (int k = 0; k < reps_work; ++k) comp.compose(job, ours.data());
      vb::do_not_optimize(ours.data());
    };
    const auto run_oiio = [&] {
      namespace iba = OIIO::ImageBufAlgo;
      for (int k = 0; k < reps_work; ++k) {
        for (std::size_t i = 0; i < mbuf.size(); ++i) {
          mw[i].reset(rgba_spec(kN, kN, OIIO::TypeDesc::FLOAT));
          iba::warp(mw[i], mbuf[i], mm, "triangle", 2.0f, false, OIIO::ImageBuf::WrapClamp, roi, 1);
        }
        const float ones[4] = {1, 1, 1, 1};
        iba::channel_sum(sum, mw[0], ones, roi, 1);
        for (std::size_t i = 1; i < mw.size(); ++i) {
          iba::channel_sum(part, mw[i], ones, roi, 1);
          iba::add(sum, sum, part, roi1, 1);
        }
        for (int l = 0; l < n; ++l) {
          const int ch = l % 4;
          iba::channels(w1, mw[static_cast<std::size_t>(l / 4)], 1, {&ch, 1}, {}, {}, false, 1);
          iba::div(w1, w1, sum, roi1, 1);
          const int c4[4] = {0, 0, 0, 0};
          iba::channels(w4, w1, 4, c4, {}, {}, false, 1);
          samp.reset(rgba_spec(kN, kN, OIIO::TypeDesc::FLOAT));
          iba::warp(samp, bbuf[static_cast<std::size_t>(l)], bm[static_cast<std::size_t>(l)], "triangle", 2.0f, false, OIIO::ImageBuf::WrapPeriodic, roi, 1);
          if (l == 0) iba::mul(acc, samp, w4, roi, 1);
          else iba::mad(acc, samp, w4, acc, roi, 1);
        }
        acc.get_pixels(roi, OIIO::TypeDesc::UINT8, theirs.data());
      }
      vb::do_not_optimize(theirs.data());
    };
    run_ours();
    run_oiio();
    const Diff d = compare(ours, theirs);
    const std::string name = "compose_" + std::to_string(n);
    nlohmann::json params = {{"layers", n}, {"active_layers", work.layers}, {"reference", "ImageBufAlgo warp (triangle) masks and brushes, channel_sum, div, mad, to uint8"}};
    params.update(diff_json(d));
    print_diff(name, d);
    std::vector<std::uint8_t> exact(kTexels * 4);
    compose_exact(job, exact.data());
    const Diff dx = compare(ours, exact);
    params["exact"] = diff_json(dx);
    std::printf("  %s: max |ours - exact (double)| per channel R %d G %d B %d A %d; %zu of %zu texels differ\n", name.c_str(), dx.max_abs[0],
                dx.max_abs[1], dx.max_abs[2], dx.max_abs[3], dx.texels_off, kTexels);
    std::printf("  %s: %u of %d layers active under the tile\n", name.c_str(), work.layers, n);
    print_rates(h.compare({.name = name, .metric = vb::Metric::kOpsPerS, .work = static_cast<double>(kTexels) * reps_work, .params = params, .target_ratio = 2.0},
                          {"compose", {}, run_ours}, {"oiio_pipeline", {}, run_oiio}));
    // The row kernels against the per-texel loop they replaced (compose_reference, the same
    // bytes), each path forced: the speed-up of the rewrite, measured in the same run.
    std::vector<std::uint8_t> ref(kTexels * 4), gen(kTexels * 4);
    compose_reference(job, ref.data());
    comp.compose(job, gen.data(), ComposePath::kGeneric);
    const bool same = ours == ref && gen == ref;
    std::printf("  %s: compose (every path) %s compose_reference\n", name.c_str(), same ? "== (bytes)" : "!= (BUG)");
    if (!same) h.missed_target();
    const auto run_ref = [&] {
      for (int k = 0; k < reps_work; ++k) compose_reference(job, ref.data());
      vb::do_not_optimize(ref.data());
    };
    const auto run_gen = [&] {
      for (int k = 0; k < reps_work; ++k) comp.compose(job, gen.data(), ComposePath::kGeneric);
      vb::do_not_optimize(gen.data());
    };
    const nlohmann::json rparams = {{"layers", n}, {"reference", "compose_reference: the per-texel loop before the row kernels"}, {"same_bytes", same}};
    print_rates(h.compare({.name = "rows_vs_loop_" + std::to_string(n), .metric = vb::Metric::kOpsPerS, .work = static_cast<double>(kTexels) * reps_work, .params = rparams},
                          {"compose", {}, run_ours}, {"compose_reference", {}, run_ref}), "compose_reference");
    print_rates(h.compare({.name = "generic_vs_loop_" + std::to_string(n), .metric = vb::Metric::kOpsPerS, .work = static_cast<double>(kTexels) * reps_work, .params = rparams},
                          {"compose_generic", {}, run_gen}, {"compose_reference", {}, run_ref}), "compose_reference");
  }
  return h.finish();
}
