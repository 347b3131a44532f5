#include "stream/produce/atlas.h"

#include <fmt/format.h>

#include <algorithm>

#include "core/error.h"

namespace vtsim::produce {

namespace {

bool is_pow2(int v) { return v > 0 && (v & (v - 1)) == 0; }

std::uint8_t atlas_mix(std::uint8_t a, std::uint8_t b, int alpha256) {  // (1-alpha) a + alpha b, alpha in 1/256
  return static_cast<std::uint8_t>((a * (256 - alpha256) + b * alpha256 + 128) >> 8);
}

}  // namespace

std::vector<Rgba8> brush_mips(const Rgba8& brush) {
  std::vector<Rgba8> out{brush};
  while (out.back().width > 1 && out.back().height > 1) {
    const Rgba8& p = out.back();
    Rgba8 q;
    q.width = p.width / 2;
    q.height = p.height / 2;
    q.texels.resize(static_cast<std::size_t>(q.width) * static_cast<std::size_t>(q.height) * 4);
    for (int y = 0; y < q.height; ++y)
      for (int x = 0; x < q.width; ++x)
        for (int c = 0; c < 4; ++c) {
          const auto at = [&](int xx, int yy) {
            return static_cast<int>(p.texels[(static_cast<std::size_t>(yy) * static_cast<std::size_t>(p.width) + static_cast<std::size_t>(xx)) * 4 + static_cast<std::size_t>(c)]);
          };
          const int s = at(2 * x, 2 * y) + at(2 * x + 1, 2 * y) + at(2 * x, 2 * y + 1) + at(2 * x + 1, 2 * y + 1);
          q.texels[(static_cast<std::size_t>(y) * static_cast<std::size_t>(q.width) + static_cast<std::size_t>(x)) * 4 + static_cast<std::size_t>(c)] =
              static_cast<std::uint8_t>((s + 2) >> 2);  // round half up
        }
    out.push_back(std::move(q));
  }
  return out;
}

void apply_transition(Rgba8& b, int t) {
  if (t <= 0) return;
  const int s = b.width;
  // Weight of the mirrored texel at distance d from the seam: 0.5 (1 - (d + 0.5) / t), so the two
  // sides meet near their mean at the seam and the brush is untouched from t on. In 1/256.
  const auto alpha = [t](int d) { return static_cast<int>(128.0 * (1.0 - (d + 0.5) / t) + 0.5); };
  const Rgba8 src = b;
  // Columns, then rows, from the column-faded image.
  for (int y = 0; y < b.height; ++y)
    for (int d = 0; d < t; ++d)
      for (int c = 0; c < 4; ++c) {
        const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(s);
        const std::size_t l = (row + static_cast<std::size_t>(d)) * 4 + static_cast<std::size_t>(c);
        const std::size_t r = (row + static_cast<std::size_t>(s - 1 - d)) * 4 + static_cast<std::size_t>(c);
        b.texels[l] = atlas_mix(src.texels[l], src.texels[r], alpha(d));
        b.texels[r] = atlas_mix(src.texels[r], src.texels[l], alpha(d));
      }
  const Rgba8 mid = b;
  for (int d = 0; d < t; ++d)
    for (int x = 0; x < s; ++x)
      for (int c = 0; c < 4; ++c) {
        const std::size_t l = (static_cast<std::size_t>(d) * static_cast<std::size_t>(s) + static_cast<std::size_t>(x)) * 4 + static_cast<std::size_t>(c);
        const std::size_t r = (static_cast<std::size_t>(b.height - 1 - d) * static_cast<std::size_t>(s) + static_cast<std::size_t>(x)) * 4 + static_cast<std::size_t>(c);
        b.texels[l] = atlas_mix(mid.texels[l], mid.texels[r], alpha(d));
        b.texels[r] = atlas_mix(mid.texels[r], mid.texels[l], alpha(d));
      }
}

Atlas build_atlas(const std::vector<Rgba8>& brushes, const std::vector<std::string>& names, const AtlasParams& p) {
  const auto name = [&](std::size_t i) { return i < names.size() ? names[i] : fmt::format("brush {}", i); };
  if (brushes.empty()) throw InputError("brushes", "no brush images given");
  if (p.cols < 1) throw InputError("cols", fmt::format("{}: must be >= 1", p.cols));
  if (p.rows < 0) throw InputError("rows", fmt::format("{}: must be >= 0 (0 = as many as the brushes need)", p.rows));
  if (p.border < 0) throw InputError("border", fmt::format("{}: must be >= 0 texels", p.border));
  if (p.transition < 0) throw InputError("transition", fmt::format("{}: must be >= 0 texels", p.transition));
  if (p.max_side < 1) throw InputError("max_side", fmt::format("{}: must be >= 1 texel", p.max_side));
  const Rgba8& first = brushes[0];
  for (std::size_t i = 0; i < brushes.size(); ++i) {
    const Rgba8& b = brushes[i];
    if (b.width != b.height) throw InputError(name(i), fmt::format("brush is {}x{}: brushes must be square", b.width, b.height));
    if (!is_pow2(b.width)) throw InputError(name(i), fmt::format("brush side {} is not a power of two", b.width));
    if (b.texels.size() != static_cast<std::size_t>(b.width) * static_cast<std::size_t>(b.height) * 4)
      throw InputError(name(i), "brush texels are not width x height x 4 bytes");
    if (b.width != first.width)
      throw InputError(name(i), fmt::format("brush is {0}x{0} but {1} is {2}x{2}: all brushes must be the same size", b.width,
                                            name(0), first.width));
  }
  const int s = first.width;
  const int cols = p.cols;
  const int rows = p.rows > 0 ? p.rows : (static_cast<int>(brushes.size()) + cols - 1) / cols;
  if (static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows) < brushes.size())
    throw InputError("rows", fmt::format("{} brushes do not fit {} x {} = {} cells", brushes.size(), cols, rows, cols * rows));
  if (2 * p.transition > s)
    throw InputError("transition", fmt::format("{} texels at each edge of a {}-texel brush: at most half the side", p.transition, s));
  const long long cell0 = static_cast<long long>(s) + 2LL * p.border;
  if (cell0 * cols > p.max_side || cell0 * rows > p.max_side)
    throw InputError("cols", fmt::format("an atlas of {} x {} cells of {} texels (S {} + 2 x border {}) is {} x {} texels, over the "
                                         "largest side {}",
                                         cols, rows, cell0, s, p.border, cell0 * cols, cell0 * rows, p.max_side));

  std::vector<std::vector<Rgba8>> mips;
  mips.reserve(brushes.size());
  for (const Rgba8& b : brushes) {
    Rgba8 t = b;
    apply_transition(t, p.transition);
    mips.push_back(brush_mips(t));
  }

  Atlas a;
  a.cols = cols;
  a.rows = rows;
  a.brushes = static_cast<int>(brushes.size());
  a.side = s;
  a.border = p.border;
  a.transition = p.transition;
  a.constant_border = p.constant_border;
  for (int m = 0; (s >> m) >= 1; ++m) {
    int nm = p.border;
    if (!p.constant_border && p.border > 0) {
      if (p.border % (1 << m) != 0) break;  // N / 2^m not a whole texel: the chain no longer aligns
      nm = p.border >> m;
    }
    AtlasLevel lv;
    lv.brush_side = s >> m;
    lv.border = nm;
    lv.cell = lv.brush_side + 2 * nm;
    lv.width = lv.cell * cols;
    lv.height = lv.cell * rows;
    lv.rgba.assign(static_cast<std::size_t>(lv.width) * static_cast<std::size_t>(lv.height) * 4, 0);
    const int sm = lv.brush_side;
    for (int b = 0; b < a.brushes; ++b) {
      const Rgba8& src = mips[static_cast<std::size_t>(b)][static_cast<std::size_t>(m)];
      for (int y = -nm; y < sm + nm; ++y)
        for (int x = -nm; x < sm + nm; ++x) {
          // Wrapped: texel -1 is texel S_m - 1 (a border wider than the brush wraps again).
          const int wx = ((x % sm) + sm) % sm, wy = ((y % sm) + sm) % sm;
          const std::uint8_t* from = &src.texels[(static_cast<std::size_t>(wy) * static_cast<std::size_t>(sm) + static_cast<std::size_t>(wx)) * 4];
          std::copy(from, from + 4, &lv.rgba[lv.offset(cols, b, x, y)]);
        }
    }
    a.levels.push_back(std::move(lv));
  }
  return a;
}

}  // namespace vtsim::produce
