#include "stream/store/store_generator.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <memory>

#include "core/error.h"
#include "core/tile_key.h"

namespace vtsim {

using namespace store;

namespace {

// 2D gradient noise (Perlin 2002's quintic fade) with its analytic derivative. Lattice gradients
// come from a 64-bit hash of (seed, octave, ix, iy), so the field is defined everywhere without a
// permutation table and is identical on every platform (only +, *, floor on doubles).
struct NoiseSample {
  double v = 0, dx = 0, dy = 0;  // value and derivatives per lattice unit
};

constexpr double kDiag = 0.70710678118654752440;
constexpr double kGrad[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {kDiag, kDiag}, {-kDiag, kDiag}, {kDiag, -kDiag}, {-kDiag, -kDiag}};

inline const double* gradient(std::uint64_t key, std::int64_t ix, std::int64_t iy) {
  const std::uint64_t h = mix64(key ^ mix64(static_cast<std::uint64_t>(ix) * 0x9E3779B97F4A7C15ULL + static_cast<std::uint64_t>(iy)));
  return kGrad[h >> 61];
}

// The four corner gradients of the lattice cell last used by one octave: neighbouring texels
// mostly share a cell (an octave of wavelength L changes cell every L texels), so the hashes are
// computed once per cell rather than once per texel.
struct CellCache {
  std::int64_t ix = INT64_MIN, iy = INT64_MIN;
  const double *g00 = nullptr, *g10 = nullptr, *g01 = nullptr, *g11 = nullptr;
};

NoiseSample gradient_noise(std::uint64_t key, double x, double y, CellCache& c) {
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx0), iy = static_cast<std::int64_t>(fy0);
  if (ix != c.ix || iy != c.iy) {
    c = {ix, iy, gradient(key, ix, iy), gradient(key, ix + 1, iy), gradient(key, ix, iy + 1), gradient(key, ix + 1, iy + 1)};
  }
  const double fx = x - fx0, fy = y - fy0;
  const double *g00 = c.g00, *g10 = c.g10, *g01 = c.g01, *g11 = c.g11;
  const double n00 = g00[0] * fx + g00[1] * fy, n10 = g10[0] * (fx - 1) + g10[1] * fy;
  const double n01 = g01[0] * fx + g01[1] * (fy - 1), n11 = g11[0] * (fx - 1) + g11[1] * (fy - 1);
  const double u = fx * fx * fx * (fx * (fx * 6 - 15) + 10), du = 30 * fx * fx * (fx * (fx - 2) + 1);
  const double v = fy * fy * fy * (fy * (fy * 6 - 15) + 10), dv = 30 * fy * fy * (fy * (fy - 2) + 1);
  const double nx0 = n00 + u * (n10 - n00), nx1 = n01 + u * (n11 - n01);
  const double dx0 = g00[0] + u * (g10[0] - g00[0]) + du * (n10 - n00);
  const double dx1 = g01[0] + u * (g11[0] - g01[0]) + du * (n11 - n01);
  const double dy0 = g00[1] + u * (g10[1] - g00[1]);
  const double dy1 = g01[1] + u * (g11[1] - g01[1]);
  return {nx0 + v * (nx1 - nx0), dx0 + v * (dx1 - dx0), dy0 + v * (dy1 - dy0) + dv * (nx1 - nx0)};
}

// fBm: octave o has wavelength feature / 2^o (level-0 texels) and amplitude 2^-o, down to 4
// texels. At texel spacing s = 2^level an octave of wavelength L gets weight clamp(L/(2s) - 1, 0, 1):
// zero at or below Nyquist (L <= 2s), full from L >= 4s.
struct Fbm {
  std::uint64_t key;
  double feature;
  int octaves;

  Fbm(std::uint64_t seed, std::uint64_t stream, double feature_texels)
      : key(mix64(seed * 0x2545F4914F6CDD1DULL + stream)), feature(feature_texels),
        octaves(std::clamp(static_cast<int>(std::floor(std::log2(feature_texels / 4.0))) + 1, 1, kMaxOctaves)) {}

  // Value and gradient per level-0 texel at level-0 position (x, y), band-limited for `level`.
  static constexpr int kMaxOctaves = 48;
  using Cache = std::array<CellCache, kMaxOctaves>;

  NoiseSample at(double x, double y, std::uint32_t level, Cache& cache) const {
    NoiseSample s;
    const double spacing = std::ldexp(1.0, static_cast<int>(level));
    double wavelength = feature, amp = 1.0;
    for (int o = 0; o < octaves; ++o, wavelength *= 0.5, amp *= 0.5) {
      const double w = std::clamp(wavelength / (2.0 * spacing) - 1.0, 0.0, 1.0);
      if (w <= 0.0) break;  // wavelengths only shrink from here
      const NoiseSample n = gradient_noise(key + static_cast<std::uint64_t>(o), x / wavelength, y / wavelength,
                                           cache[static_cast<std::size_t>(o)]);
      s.v += w * amp * n.v;
      s.dx += w * amp * n.dx / wavelength;
      s.dy += w * amp * n.dy / wavelength;
    }
    return s;
  }
};

// Centre of texel i's level-0 footprint [i*2^l, min((i+1)*2^l, extent0)), in continuous level-0
// coordinates (texel k spans [k, k+1)).
double footprint_centre(std::uint64_t i, std::uint32_t l, std::uint64_t extent0) {
  const std::uint64_t b = i << l, e = std::min((i + 1) << l, extent0);
  return 0.5 * static_cast<double>(b + e);
}

std::uint8_t to_u8(double v) { return static_cast<std::uint8_t>(std::clamp(v, 0.0, 1.0) * 255.0 + 0.5); }

struct Rgb {
  double r, g, b;
};
Rgb mix(Rgb a, Rgb b, double t) {
  t = std::clamp(t, 0.0, 1.0);
  return {a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t};
}
double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// Terrain colours (sRGB, 0..1) by height; slope pushes towards rock.
Rgb albedo_of(double h, double slope, double detail) {
  const Rgb deep{0.05, 0.12, 0.25}, shallow{0.12, 0.32, 0.42}, sand{0.76, 0.70, 0.50}, grass{0.29, 0.45, 0.18},
      forest{0.16, 0.30, 0.12}, rock{0.45, 0.42, 0.38}, snow{0.92, 0.93, 0.95};
  Rgb c = mix(deep, shallow, smoothstep(-0.45, -0.12, h));
  c = mix(c, sand, smoothstep(-0.12, -0.08, h));
  c = mix(c, grass, smoothstep(-0.06, 0.0, h));
  c = mix(c, forest, smoothstep(0.1, 0.25, h + 0.1 * detail));
  c = mix(c, rock, smoothstep(0.35, 0.5, h) + smoothstep(0.45, 0.8, slope) * (h > -0.08 ? 1.0 : 0.0));
  c = mix(c, snow, smoothstep(0.55, 0.65, h + 0.05 * detail));
  const double k = 0.88 + 0.12 * detail;
  return {c.r * k, c.g * k, c.b * k};
}

struct Generator {
  const GenOptions& o;
  Geometry g;
  Fbm height, detail;
  double height_scale;  // height in level-0 texels per unit of h

  explicit Generator(const GenOptions& opt)
      : o(opt), height(opt.seed, 1, opt.feature_texels), detail(opt.seed, 2, std::min(opt.feature_texels, 256.0)),
        // slope of each octave ~ amplitude * pi / wavelength, the same for every octave of this
        // fBm; 0.05 * feature gives slopes of order 0.5: hills, not cliffs or plains.
        height_scale(0.05 * opt.feature_texels) {
    const std::uint32_t levels = opt.levels ? opt.levels : full_level_count(opt.width, opt.height);
    g = Geometry::make(opt.width, opt.height, opt.tile, opt.border, levels, static_cast<std::uint32_t>(opt.layers.size()));
  }

  // All layers of one tile; out[layer] has (T+2B)^2 * channels bytes.
  void tile(std::uint32_t level, std::uint64_t tx, std::uint64_t ty, std::vector<std::vector<std::uint8_t>>& out) const {
    const std::uint32_t side = g.stored_side();
    const auto wmax = static_cast<std::int64_t>(g.level_width(level)) - 1, hmax = static_cast<std::int64_t>(g.level_height(level)) - 1;
    const auto x0 = static_cast<std::int64_t>(tx * g.tile) - g.border, y0 = static_cast<std::int64_t>(ty * g.tile) - g.border;
    out.resize(o.layers.size());
    for (std::size_t l = 0; l < o.layers.size(); ++l)
      out[l].assign(static_cast<std::size_t>(side) * side * (o.layers[l].kind == GenKind::height ? 1 : 3), 0);
    auto hcache = std::make_unique<Fbm::Cache>(), dcache = std::make_unique<Fbm::Cache>();
    bool need_detail = false;
    for (const auto& L : o.layers) need_detail |= L.kind == GenKind::albedo;
    for (std::uint32_t j = 0; j < side; ++j) {
      const auto ly = static_cast<std::uint64_t>(std::clamp<std::int64_t>(y0 + j, 0, hmax));
      const double py = footprint_centre(ly, level, g.height);
      for (std::uint32_t i = 0; i < side; ++i) {
        const auto lx = static_cast<std::uint64_t>(std::clamp<std::int64_t>(x0 + i, 0, wmax));
        const double px = footprint_centre(lx, level, g.width);
        const NoiseSample h = height.at(px, py, level, *hcache);
        const double gx = h.dx * height_scale, gy = h.dy * height_scale;
        const double slope = std::sqrt(gx * gx + gy * gy);
        const double d = need_detail ? detail.at(px, py, level, *dcache).v * 1.4 : 0.0;
        const std::size_t t = static_cast<std::size_t>(j) * side + i;
        for (std::size_t l = 0; l < o.layers.size(); ++l) {
          std::uint8_t* p = out[l].data();
          switch (o.layers[l].kind) {
            case GenKind::albedo: {
              const Rgb c = albedo_of(h.v, slope, d);
              p[3 * t] = to_u8(c.r), p[3 * t + 1] = to_u8(c.g), p[3 * t + 2] = to_u8(c.b);
              break;
            }
            case GenKind::normal: {
              const double inv = 1.0 / std::sqrt(gx * gx + gy * gy + 1.0);
              p[3 * t] = to_u8(0.5 - 0.5 * gx * inv), p[3 * t + 1] = to_u8(0.5 - 0.5 * gy * inv), p[3 * t + 2] = to_u8(0.5 + 0.5 * inv);
              break;
            }
            case GenKind::height:
              p[t] = to_u8(0.5 + 0.5 * h.v);
              break;
          }
        }
      }
    }
  }
};

StoreSpec spec_of(const GenOptions& o) {
  StoreSpec s;
  s.width = o.width;
  s.height = o.height;
  s.tile = o.tile;
  s.border = o.border;
  s.levels = o.levels;
  for (const GenLayer& L : o.layers)
    s.layers.push_back({L.name, L.kind == GenKind::height ? 1u : 3u, L.codec,
                        L.kind == GenKind::albedo ? Transfer::srgb : Transfer::linear});
  return s;
}

void check_options(const GenOptions& o) {
  if (!(o.feature_texels >= 4.0 && o.feature_texels <= 1e12))
    throw InputError("--feature", "the feature size must be 4..1e12 texels, got " + fmt::format("{:g}", o.feature_texels));
}

}  // namespace

std::vector<GenLayer> parse_gen_layers(const std::string& text, const std::string& where) {
  std::vector<GenLayer> layers;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t comma = std::min(text.find(',', pos), text.size());
    const std::string item = text.substr(pos, comma - pos);
    const std::size_t colon = item.find(':');
    GenLayer L;
    L.name = item.substr(0, colon);
    if (L.name.rfind("albedo", 0) == 0) L.kind = GenKind::albedo;
    else if (L.name.rfind("normal", 0) == 0) L.kind = GenKind::normal;
    else if (L.name.rfind("height", 0) == 0) L.kind = GenKind::height;
    else throw InputError(where, "layer '" + L.name + "': a generated layer is named albedo*, normal* or height*");
    for (const GenLayer& before : layers)
      if (before.name == L.name) throw InputError(where, "layer name '" + L.name + "' is used twice");
    L.codec = colon == std::string::npos ? CodecSpec{CodecId::zstd, default_codec_param(CodecId::zstd)}
                                         : parse_codec_spec(item.substr(colon + 1), where);
    layers.push_back(L);
    pos = comma + 1;
  }
  return layers;
}

BuildResult generate_store(const GenOptions& o, const std::string& out_path, const ProgressFn& progress) {
  check_options(o);
  StoreWriter writer(out_path, spec_of(o));  // validates sizes and layers
  const Generator gen(o);
  const Geometry& g = writer.geometry();
  std::uint64_t done = 0;
  const double total = static_cast<double>(g.tiles_per_layer);
  for (std::uint32_t l = 0; l < g.levels; ++l) {
    const std::uint64_t cols = g.cols[l], tiles = cols * g.rows[l];
    encode_in_order(
        writer, tiles, o.threads,
        [&](std::uint64_t i, std::vector<EncodedTile>& out) {
          std::vector<std::vector<std::uint8_t>> texels;
          const std::uint64_t x = i % cols, y = i / cols;
          gen.tile(l, x, y, texels);
          for (std::uint32_t layer = 0; layer < g.layers; ++layer)
            out.push_back(writer.encode(TileKey(layer, l, static_cast<std::int64_t>(x), static_cast<std::int64_t>(y)), texels[layer].data()));
        },
        [&](double f) {
          if (progress) progress((static_cast<double>(done) + f * static_cast<double>(tiles)) / total);
        });
    done += tiles;
  }
  writer.commit();
  BuildResult r;
  r.tiles = g.tile_count();
  r.file_bytes = writer.header().file_bytes;
  r.stored_bytes = writer.stored_bytes();
  r.decoded_bytes = writer.decoded_bytes();
  return r;
}

std::vector<std::uint8_t> generate_tile(const GenOptions& o, std::uint32_t layer, std::uint32_t level, std::uint64_t tx,
                                        std::uint64_t ty) {
  check_options(o);
  const Generator gen(o);
  std::vector<std::vector<std::uint8_t>> texels;
  gen.tile(level, tx, ty, texels);
  return texels.at(layer);
}

}  // namespace vtsim
