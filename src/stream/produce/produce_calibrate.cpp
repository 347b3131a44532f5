#include "stream/produce/produce_calibrate.h"

#include <algorithm>
#include <array>
#include <map>
#include <chrono>
#include <cmath>
#include <string_view>

#include <time.h>

#include <fmt/format.h>

#include "core/error.h"
#include "core/input_file.h"
#include "core/text.h"

namespace vtsim::produce {

namespace {

std::uint64_t pcal_mix(std::uint64_t x) {  // splitmix64's finaliser
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

constexpr int kPcalUnknowns = 5;  // per_tile_us, per_texel_ns, per_layer_texel_ns, per_decal_us, per_decal_texel_ns

// The model's terms of one sample, in ns per unit of each unknown.
std::array<double, kPcalUnknowns> pcal_terms(const ProduceSample& s) {
  const double t = static_cast<double>(s.texels);
  return {1000.0, t, t * static_cast<double>(s.layers), 1000.0 * static_cast<double>(s.decals), static_cast<double>(s.decal_texels)};
}

// Weighted least squares over the unknowns in `use` (others fixed at 0); false when singular.
bool pcal_solve(const std::vector<ProduceSample>& samples, const std::array<bool, kPcalUnknowns>& use, bool relative,
                std::array<double, kPcalUnknowns>& x) {
  std::vector<int> cols;
  for (int i = 0; i < kPcalUnknowns; ++i)
    if (use[static_cast<std::size_t>(i)]) cols.push_back(i);
  const std::size_t n = cols.size();
  std::vector<double> a(n * (n + 1), 0.0);  // augmented normal equations
  for (const ProduceSample& s : samples) {
    const auto t = pcal_terms(s);
    const double w = relative ? 1.0 / (s.ns * s.ns) : 1e-6;  // relative error, or absolute (scaled: the normal equations are rescaled below)
    for (std::size_t r = 0; r < n; ++r) {
      const double tr = t[static_cast<std::size_t>(cols[r])];
      for (std::size_t c = 0; c < n; ++c) a[r * (n + 1) + c] += w * tr * t[static_cast<std::size_t>(cols[c])];
      a[r * (n + 1) + n] += w * tr * s.ns;
    }
  }
  // Scaled to a unit diagonal, so "singular" is a relative test.
  std::vector<double> scale(n);
  for (std::size_t r = 0; r < n; ++r) {
    if (!(a[r * (n + 1) + r] > 0)) return false;  // a term that is 0 in every sample
    scale[r] = std::sqrt(a[r * (n + 1) + r]);
  }
  for (std::size_t r = 0; r < n; ++r) {
    for (std::size_t c = 0; c < n; ++c) a[r * (n + 1) + c] /= scale[r] * scale[c];
    a[r * (n + 1) + n] /= scale[r];
  }
  for (std::size_t c = 0; c < n; ++c) {  // Gauss-Jordan, partial pivoting
    std::size_t p = c;
    for (std::size_t r = c + 1; r < n; ++r)
      if (std::fabs(a[r * (n + 1) + c]) > std::fabs(a[p * (n + 1) + c])) p = r;
    if (std::fabs(a[p * (n + 1) + c]) < 1e-9) return false;
    for (std::size_t k = 0; k <= n; ++k) std::swap(a[c * (n + 1) + k], a[p * (n + 1) + k]);
    for (std::size_t r = 0; r < n; ++r) {
      if (r == c) continue;
      const double f = a[r * (n + 1) + c] / a[c * (n + 1) + c];
      for (std::size_t k = c; k <= n; ++k) a[r * (n + 1) + k] -= f * a[c * (n + 1) + k];
    }
  }
  x.fill(0.0);
  for (std::size_t r = 0; r < n; ++r) x[static_cast<std::size_t>(cols[r])] = a[r * (n + 1) + n] / a[r * (n + 1) + r] / scale[r];
  return true;
}

Rgba8 pcal_brush(int side, std::uint64_t seed) {
  // Value noise on an 8-texel lattice (smooth enough that the mips differ from the base level).
  Rgba8 im;
  im.width = im.height = side;
  im.texels.resize(static_cast<std::size_t>(side) * static_cast<std::size_t>(side) * 4);
  const int cell = std::max(1, std::min(8, side));
  const int lattice = std::max(1, side / cell);
  const auto node = [&](int x, int y, int c) {
    return static_cast<double>(pcal_mix(seed * 0x100000001b3ULL + static_cast<std::uint64_t>(((x % lattice) * 131 + (y % lattice)) * 4 + c)) & 255);
  };
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const int gx = x / cell, gy = y / cell;
      const double fx = static_cast<double>(x % cell) / cell, fy = static_cast<double>(y % cell) / cell;
      for (int c = 0; c < 4; ++c) {
        const double v = (node(gx, gy, c) * (1 - fx) + node(gx + 1, gy, c) * fx) * (1 - fy) +
                         (node(gx, gy + 1, c) * (1 - fx) + node(gx + 1, gy + 1, c) * fx) * fy;
        im.texels[(static_cast<std::size_t>(y) * static_cast<std::size_t>(side) + static_cast<std::size_t>(x)) * 4 +
                  static_cast<std::size_t>(c)] = c == 3 ? std::uint8_t{255} : static_cast<std::uint8_t>(std::lround(v));
      }
    }
  return im;
}

}  // namespace

std::int64_t thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

ProduceFit fit_produce_model(const std::vector<ProduceSample>& samples, const ProduceModel& base, bool relative) {
  std::array<bool, kPcalUnknowns> use = {true, true, true, false, false};
  bool vary = false, texels_seen = false, ratio_varies = false;
  double ratio = -1;  // decal texels per decal
  for (const ProduceSample& s : samples) {
    if (!(s.ns > 0)) throw InputError("produce samples", fmt::format("a sample of {} texels took {} ns (must be > 0)", s.texels, s.ns));
    vary |= s.decals != samples.front().decals;
    texels_seen |= s.decal_texels > 0;
    if (s.decals > 0) {
      const double r = static_cast<double>(s.decal_texels) / s.decals;
      if (ratio < 0) ratio = r;
      ratio_varies |= std::fabs(r - ratio) > 1e-9 * std::max(1.0, ratio);
    }
  }
  use[3] = vary && (!texels_seen || ratio_varies);
  use[4] = vary && texels_seen;
  ProduceFit fit;
  fit.model = base;
  fit.relative = relative;
  fit.decals_fitted = use[3] || use[4];
  // A replay's own tiles (samples_from_tiles) may all blend the same layers, or all be full tiles:
  // a column is then proportional to another and the pair cannot be told apart. The cost is folded
  // into the term that stays (exact for these samples; per_layer_texel_ns then holds for this layer
  // count only), and said.
  bool layers_vary = false, texels_vary = false;
  for (const ProduceSample& s : samples) {
    layers_vary |= s.layers != samples.front().layers;
    texels_vary |= s.texels != samples.front().texels;
  }
  if (!samples.empty() && !layers_vary && samples.front().layers > 0) {
    use[1] = false;
    fit.notes.push_back(fmt::format("every sample blends {} layers: per_texel_ns folded into per_layer_texel_ns (fixed at 0; the fit holds "
                                    "for {} layers)",
                                    samples.front().layers, samples.front().layers));
  }
  if (!samples.empty() && !texels_vary) {
    use[0] = false;
    fit.notes.push_back(fmt::format("every sample is {} texels: per_tile_us folded into the per-texel terms (fixed at 0)", samples.front().texels));
  }
  const int unknowns = static_cast<int>(std::count(use.begin(), use.end(), true));
  if (static_cast<int>(samples.size()) < unknowns)
    throw InputError("produce samples", fmt::format("{} samples for {} unknowns", samples.size(), unknowns));
  std::array<double, kPcalUnknowns> x{};
  static constexpr const char* kNames[kPcalUnknowns] = {"per_tile_us", "per_texel_ns", "per_layer_texel_ns", "per_decal_us",
                                                         "per_decal_texel_ns"};
  for (int round = 0; round < kPcalUnknowns; ++round) {
    if (!pcal_solve(samples, use, relative, x)) {
      fit.notes.push_back("the samples do not separate the terms (singular); vary texels and layers");
      throw InputError("produce samples", fit.notes.back());
    }
    int worst = -1;
    for (int i = 0; i < kPcalUnknowns; ++i)
      if (use[static_cast<std::size_t>(i)] && x[static_cast<std::size_t>(i)] < 0 &&
          (worst < 0 || x[static_cast<std::size_t>(i)] < x[static_cast<std::size_t>(worst)]))
        worst = i;
    if (worst < 0) break;
    fit.notes.push_back(fmt::format("{} fitted {:.4g} < 0: fixed at 0, the rest refitted", kNames[worst], x[static_cast<std::size_t>(worst)]));
    use[static_cast<std::size_t>(worst)] = false;
  }
  fit.model.per_tile_us = x[0];  // 0 when not fitted (folded or dropped, above)
  fit.model.per_texel_ns = x[1];
  fit.model.per_layer_texel_ns = x[2];
  if (fit.decals_fitted) {
    fit.model.per_decal_us = x[3];
    fit.model.per_decal_texel_ns = x[4];
  }
  std::vector<double> rel;
  for (const ProduceSample& s : samples) {
    const double m = produce_ns(fit.model, ProduceWork{s.texels, s.layers, s.decals, s.decal_texels});
    rel.push_back(std::fabs(m - s.ns) / s.ns);
  }
  for (const ProduceSample& s : samples) {
    fit.measured_ms += s.ns * 1e-6;
    fit.model_ms += produce_ns(fit.model, ProduceWork{s.texels, s.layers, s.decals, s.decal_texels}) * 1e-6;
  }
  std::sort(rel.begin(), rel.end());
  if (!rel.empty()) {
    fit.median_rel_error = rel[rel.size() / 2];
    fit.max_rel_error = rel[rel.size() - 1];
  }
  return fit;
}

namespace {
std::vector<Rgba8> pcal_brushes(int brushes, int brush_side, std::uint64_t seed) {
  if (brushes < 1 || brushes > kMaxLayers) throw InputError("produce scene", fmt::format("{} brushes (1 to {})", brushes, kMaxLayers));
  std::vector<Rgba8> b;
  for (int i = 0; i < brushes; ++i) b.push_back(pcal_brush(brush_side, seed * 977 + static_cast<std::uint64_t>(i)));
  return b;
}
}  // namespace

ProduceScene::ProduceScene(int brushes, int brush_side, int active, int mask_side, double mask_m, std::uint64_t seed)
    : ProduceScene(pcal_brushes(brushes, brush_side, seed), {}, active, mask_side, mask_m, seed) {}

ProduceScene::ProduceScene(const std::vector<Rgba8>& b, const std::vector<std::string>& names, int active, int mask_side, double mask_m,
                           std::uint64_t seed)
    : active_(active), mask_side_(mask_side), mask_m_(mask_m) {
  const int brushes = static_cast<int>(b.size());
  if (brushes < 1 || brushes > kMaxLayers) throw InputError("produce scene", fmt::format("{} brushes (1 to {})", brushes, kMaxLayers));
  if (active < 1 || active > kMaxLayers) throw InputError("produce scene", fmt::format("{} active layers (1 to {})", active, kMaxLayers));
  // constant_border: every level covered, so a coarse clipmap level samples a coarse brush mip as the
  // terrain does (terrain_system.h, brush_mip), not level 0's neighbourhood with a long stride.
  atlas_ = build_atlas(b, names, AtlasParams{.cols = 4, .border = 4, .constant_border = true});
  const std::size_t n = static_cast<std::size_t>(mask_side) * static_cast<std::size_t>(mask_side);
  for (int m = 0; m < kMaxLayers / 4; ++m) {
    std::vector<std::uint8_t> t(n * 4, 0);
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 4; ++c)
        if (m * 4 + c < active)
          t[i * 4 + static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(16 + pcal_mix(seed ^ (i * 16 + static_cast<std::size_t>(m * 4 + c))) % 240);
    mask_texels_.push_back(std::move(t));
  }
  for (int l = 0; l < kMaxLayers; ++l) layers_.push_back(BrushLayer{l % brushes, 1.0});
  masks_.resize(mask_texels_.size());
}

CompositeJob ProduceScene::job(int layers, double period_m, double x_m, double y_m, double mask_x_m, double mask_y_m,
                               double m_per_texel, int tile, int border, std::span<const Decal> decals) const {
  return job_into(std::span<BrushLayer, kMaxLayers>(layers_.data(), kMaxLayers), std::span<WeightMask, kMaxLayers / 4>(masks_.data(), kMaxLayers / 4),
                  layers, period_m, x_m, y_m, mask_x_m, mask_y_m, m_per_texel, tile, border, decals);
}

CompositeJob ProduceScene::job_into(std::span<BrushLayer, kMaxLayers> layer_out, std::span<WeightMask, kMaxLayers / 4> mask_out,
                                    int layers, double period_m, double x_m, double y_m, double mask_x_m, double mask_y_m,
                                    double m_per_texel, int tile, int border, std::span<const Decal> decals) const {
  if (layers < 1 || layers > active_) throw InputError("produce scene", fmt::format("{} layers (1 to {} active)", layers, active_));
  for (std::size_t l = 0; l < layer_out.size(); ++l) layer_out[l] = BrushLayer{layers_[l].cell, period_m};
  const int nmasks = (layers + 3) / 4;
  for (int m = 0; m < nmasks; ++m)
    mask_out[static_cast<std::size_t>(m)] =
        WeightMask{mask_side_, mask_side_, mask_texels_[static_cast<std::size_t>(m)].data(), mask_x_m, mask_y_m, mask_m_ / mask_side_};
  CompositeJob j;
  j.atlas = &atlas_;
  j.layers = std::span<const BrushLayer>(layer_out.data(), static_cast<std::size_t>(layers));
  j.masks = std::span<const WeightMask>(mask_out.data(), static_cast<std::size_t>(nmasks));
  j.decals = decals;
  j.origin_x_m = x_m;
  j.origin_y_m = y_m;
  j.m_per_texel = m_per_texel;
  j.tile = tile;
  j.border = border;
  return j;
}

std::vector<ProduceSample> measure_compositor(const ProduceMeasureOptions& o, const ProduceProgress& progress) {
  if (o.repeats < 1) throw InputError("produce calibration", "repeats must be >= 1");
  int most = 1;
  for (int l : o.layers) {
    if (l < 1 || l > kMaxLayers) throw InputError("produce calibration", fmt::format("{} layers (1 to {})", l, kMaxLayers));
    most = std::max(most, l);
  }
  if (progress) progress("building the brush atlas");
  const double mask_m = 512.0;  // a terrain sector (VT Terrain Design's 512 m); tiles below sit inside it
  const ProduceScene scene(std::min(most, kMaxLayers), o.brush_side, most, 512, mask_m, o.seed);
  Compositor comp;
  std::vector<std::uint8_t> out;
  std::vector<ProduceSample> samples;
  using Clock = std::chrono::steady_clock;
  for (int tile : o.tiles)
    for (int border : o.borders) {
      if (tile < 1 || border < 0) throw InputError("produce calibration", fmt::format("tile {} border {}", tile, border));
      const int side = tile + 2 * border;
      out.assign(static_cast<std::size_t>(side) * static_cast<std::size_t>(side) * 4, 0);
      for (int layers : o.layers)
        for (int nd : o.decals) {
          if (progress) progress(fmt::format("compositor: tile {} border {} layers {} decals {}", tile, border, layers, nd));
          // Decals spread over the tile, each tile/8 texels a side (drawn by the compositor, counted
          // by count_work), placed relative to the tile: every repetition draws all of them.
          const double span = tile * o.m_per_texel;
          std::vector<Decal> decals;
          const auto place = [&](double x, double y) {
            decals.clear();
            for (int d = 0; d < nd; ++d) {
              const double f = (d + 0.5) / nd;
              decals.push_back(Decal{x + f * span, y + f * span, x + f * span + span / 8, y + f * span + span / 8});
            }
          };
          std::vector<double> ns;
          const int reps = o.repeats + 1;  // the first call warms the caches and the scratch rows
          for (int r = 0; r < reps; ++r) {
            // Each repetition at another place of the sector: a different part of the brushes and masks.
            const double x = 100 + 37.0 * r, y = 100 + 53.0 * r;
            place(x, y);
            const CompositeJob j = scene.job(layers, 1.0, x, y, 0.0, 0.0, o.m_per_texel, tile, border, decals);
            const auto t0 = Clock::now();
            const std::int64_t c0 = thread_cpu_ns();
            comp.compose(j, out.data());
            const std::int64_t c1 = thread_cpu_ns();
            const auto t1 = Clock::now();
            const double wall = static_cast<double>(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
            if (r > 0) ns.push_back(o.cpu_time ? static_cast<double>(c1 - c0) : wall);
          }
          std::sort(ns.begin(), ns.end());
          place(100, 100);
          const ProduceWork w = count_work(scene.job(layers, 1.0, 100, 100, 0, 0, o.m_per_texel, tile, border, decals));
          if (w.decals != static_cast<std::uint32_t>(nd))
            throw std::logic_error(fmt::format("produce calibration: {} of {} decals over the tile", w.decals, nd));
          samples.push_back(ProduceSample{w.texels, w.layers, w.decals, ns[ns.size() / 2], tile, border, w.decal_texels});
        }
    }
  return samples;
}

namespace {

constexpr std::string_view kProducedTilesHeader = "level,texels,layers,decals,decal_texels,wall_us,cpu_us";

}  // namespace

std::string produced_tiles_csv(const std::vector<ProducedTile>& tiles) {
  std::string s(kProducedTilesHeader);
  s += '\n';
  for (const ProducedTile& t : tiles)
    s += fmt::format("{},{},{},{},{},{:.3f},{:.3f}\n", t.level, t.work.texels, t.work.layers, t.work.decals, t.work.decal_texels,
                     t.wall_ns / 1000, t.cpu_ns / 1000);
  return s;
}

std::vector<ProducedTile> read_produced_tiles_csv(const std::string& path) {
  // 64 bytes a row at most in practice: 1 GiB is ~16 M tiles, hours of production.
  const std::string text = read_regular_file(path, std::uint64_t{1} << 30, "not a produced-tiles CSV");
  std::vector<ProducedTile> tiles;
  std::string_view rest = text;
  long long line_no = 0;
  static constexpr const char* kCols[] = {"level", "texels", "layers", "decals", "decal_texels", "wall_us", "cpu_us"};
  while (!rest.empty()) {
    const std::size_t nl = rest.find('\n');
    const std::string_view line = text::trim_line(rest.substr(0, nl));
    rest.remove_prefix(nl == std::string_view::npos ? rest.size() : nl + 1);
    ++line_no;
    if (line_no == 1) {
      if (line != kProducedTilesHeader)
        throw InputError(at_line(path, 1), fmt::format("header '{}' is not '{}' (write the file with `vtsim replay --clock real "
                                                       "--produce-samples`)",
                                                       line.substr(0, 80), kProducedTilesHeader));
      continue;
    }
    if (line.empty()) continue;
    std::array<std::string_view, 7> f;
    std::size_t n = 0, at = 0;
    for (; n < f.size() + 1 && at <= line.size(); ++n) {
      const std::size_t comma = std::min(line.find(',', at), line.size());
      if (n < f.size()) f[n] = text::trim_line(line.substr(at, comma - at));
      at = comma + 1;
    }
    if (n != f.size()) throw InputError(at_line(path, line_no), fmt::format("{} fields, expected {} ({})", n, f.size(), kProducedTilesHeader));
    ProducedTile t;
    double wall_us = 0, cpu_us = 0;
    const auto bad = [&](int col, const char* want) {
      return InputError(at_line(path, line_no), fmt::format("column '{}': '{}' is not {}", kCols[col], f[static_cast<std::size_t>(col)].substr(0, 40), want));
    };
    if (!text::parse_whole(f[0], t.level) || t.level > 63) throw bad(0, "a level 0 to 63");
    if (!text::parse_whole(f[1], t.work.texels) || t.work.texels == 0) throw bad(1, "a texel count >= 1");
    if (!text::parse_whole(f[2], t.work.layers) || t.work.layers > 1024) throw bad(2, "a layer count 0 to 1024");
    if (!text::parse_whole(f[3], t.work.decals)) throw bad(3, "a decal count");
    if (!text::parse_whole(f[4], t.work.decal_texels)) throw bad(4, "a texel count");
    if (!text::parse_whole(f[5], wall_us) || !std::isfinite(wall_us) || !(wall_us > 0)) throw bad(5, "a time > 0, us");
    if (!text::parse_whole(f[6], cpu_us) || !std::isfinite(cpu_us) || cpu_us < 0) throw bad(6, "a time >= 0, us");
    t.wall_ns = wall_us * 1000;
    t.cpu_ns = cpu_us * 1000;
    tiles.push_back(t);
  }
  if (line_no == 0) throw InputError(path, fmt::format("empty: expected the header '{}'", kProducedTilesHeader));
  return tiles;
}

std::vector<ProduceSample> samples_from_tiles(const std::vector<ProducedTile>& tiles, bool cpu_time) {
  std::vector<ProduceSample> out;
  out.reserve(tiles.size());
  for (const ProducedTile& t : tiles) {
    const int side = static_cast<int>(std::lround(std::sqrt(static_cast<double>(t.work.texels))));
    out.push_back(ProduceSample{t.work.texels, t.work.layers, t.work.decals, cpu_time ? t.cpu_ns : t.wall_ns, side, 0, t.work.decal_texels});
  }
  return out;
}

std::string produce_profile_toml(const ProduceFit& fit, const std::vector<ProduceSample>& samples) {
  std::string s = fit.relative ? "# The produce stage's cost model, fitted by `vtsim calibrate --produce` to the CPU compositor on\n"
                                 "# one thread of this machine (docs/produced.md, \"Calibration\").\n"
                               : "# The produce stage's cost model, fitted by `vtsim calibrate --samples` to the tiles real-clock\n"
                                 "# replays composed, least squares on the absolute error (docs/produced.md, \"Calibrating from\n"
                                 "# the replay's own tiles\").\n";
  s += fmt::format("# {} points, median relative error {:.1f} %, max {:.1f} %\n", samples.size(), 100 * fit.median_rel_error,
                   100 * fit.max_rel_error);
  for (const std::string& n : fit.notes) s += "# note: " + n + "\n";
  s += fmt::format("# all samples together: measured {:.1f} ms, model {:.1f} ms ({:+.1f} %)\n", fit.measured_ms, fit.model_ms,
                   fit.measured_ms > 0 ? 100 * (fit.model_ms / fit.measured_ms - 1) : 0.0);
  constexpr std::size_t kListed = 100;  // a calibration's points are listed; a replay's tiles (thousands) grouped
  if (samples.size() <= kListed) {
    s += "#   tile border layers decals decal_texels   measured_us   model_us\n";
    for (const ProduceSample& p : samples)
      s += fmt::format("#   {:4} {:6} {:6} {:6} {:12}   {:11.1f}   {:8.1f}\n", p.tile, p.border, p.layers, p.decals, p.decal_texels, p.ns / 1000,
                       produce_ns(fit.model, ProduceWork{p.texels, p.layers, p.decals, p.decal_texels}) / 1000);
  } else {
    struct Group {
      std::size_t n = 0;
      double measured = 0, model = 0;
    };
    std::map<std::pair<std::uint64_t, std::uint32_t>, Group> groups;  // (texels, layers), in order
    for (const ProduceSample& p : samples) {
      Group& g = groups[{p.texels, p.layers}];
      ++g.n;
      g.measured += p.ns;
      g.model += produce_ns(fit.model, ProduceWork{p.texels, p.layers, p.decals, p.decal_texels});
    }
    s += "#   texels layers  tiles   measured_us (mean)   model_us (mean)\n";
    for (const auto& [k, g] : groups)
      s += fmt::format("#   {:6} {:6} {:6}   {:18.1f}   {:15.1f}\n", k.first, k.second, g.n, g.measured / static_cast<double>(g.n) / 1000,
                       g.model / static_cast<double>(g.n) / 1000);
  }
  s += "[produce]\n";
  s += fmt::format("per_tile_us = {:.4g}\n", fit.model.per_tile_us);
  s += fmt::format("per_texel_ns = {:.4g}\n", fit.model.per_texel_ns);
  s += fmt::format("per_layer_texel_ns = {:.4g}\n", fit.model.per_layer_texel_ns);
  s += fmt::format("per_decal_us = {:.4g}{}\n", fit.model.per_decal_us, fit.decals_fitted ? "" : "  # not measured: kept");
  s += fmt::format("per_decal_texel_ns = {:.4g}{}\n", fit.model.per_decal_texel_ns, fit.decals_fitted ? "" : "  # not measured: kept");
  s += fmt::format("workers = {}\n", fit.model.workers);
  return s;
}

}  // namespace vtsim::produce
