#include "stream/produce/decal_layer.h"

#include <algorithm>
#include <cmath>

#include "core/tile_key.h"

namespace vtsim::produce {

namespace {
// Footprints: dark, mostly opaque; static decals ("damage"): muted earth tones from their hash.
constexpr std::array<std::uint8_t, 4> kFootprint = {38, 30, 22, 200};
}  // namespace

DecalLayer::DecalLayer(const DecalLayerParams& p) : p_(p) {
  bucket_.resize(static_cast<std::size_t>(std::max(0, p.sectors_x * p.sectors_y)));
  const double w_m = static_cast<double>(p.sectors_x) * p.sector_m, h_m = static_cast<double>(p.sectors_y) * p.sector_m;
  statics_.reserve(static_cast<std::size_t>(std::max(0, p.statics)));
  for (int i = 0; i < p.statics; ++i) {
    const std::uint64_t h1 = mix64(static_cast<std::uint64_t>(p.seed) * 0x9E3779B97F4A7C15ULL + 2 * static_cast<std::uint64_t>(i));
    const std::uint64_t h2 = mix64(h1 ^ 0xD1B54A32D192ED03ULL);
    const double x = static_cast<double>(h1 >> 11) * 0x1p-53 * w_m, y = static_cast<double>(h2 >> 11) * 0x1p-53 * h_m;
    const int sx = std::min(p.sectors_x - 1, static_cast<int>(x / p.sector_m)), sy = std::min(p.sectors_y - 1, static_cast<int>(y / p.sector_m));
    bucket_[static_cast<std::size_t>(sy * p.sectors_x + sx)].push_back(static_cast<std::uint32_t>(statics_.size()));
    const auto c = [&](int sh, int base, int span) { return static_cast<std::uint8_t>(base + static_cast<int>((h2 >> sh) % static_cast<std::uint64_t>(span))); };
    statics_.push_back({x, y, p.static_size_m / 2, {c(0, 70, 60), c(8, 56, 44), c(16, 40, 32), c(24, 120, 100)}});
  }
}

bool DecalLayer::add_footprint(double x_m, double y_m) {
  const std::size_t i = n_.load(std::memory_order_relaxed);  // the writer's own count
  if (i >= kMaxFootprints) return false;
  std::unique_ptr<Entry[]>& chunk = chunks_[i / kChunk];
  if (!chunk) chunk = std::make_unique<Entry[]>(kChunk);
  chunk[i % kChunk] = Entry{x_m, y_m, p_.footprint_size_m / 2, kFootprint};
  n_.store(i + 1, std::memory_order_release);
  return true;
}

template <class F>
void DecalLayer::for_each(double texel_m, double x0, double y0, double x1, double y1, F&& f) const {
  const auto overlaps = [&](const Entry& d) {
    return 2 * d.half >= texel_m && d.x + d.half > x0 && d.x - d.half < x1 && d.y + d.half > y0 && d.y - d.half < y1;
  };
  if (!bucket_.empty()) {
    // A static decal's centre lies in its sector and it is no wider than one (validated): the
    // sectors the rectangle touches and one around them hold every one that can overlap it.
    const auto sec = [&](double v, int n) { return std::clamp(static_cast<int>(std::floor(v / p_.sector_m)), 0, n - 1); };
    const int sx0 = std::max(0, sec(x0, p_.sectors_x) - 1), sx1 = std::min(p_.sectors_x - 1, sec(x1, p_.sectors_x) + 1);
    const int sy0 = std::max(0, sec(y0, p_.sectors_y) - 1), sy1 = std::min(p_.sectors_y - 1, sec(y1, p_.sectors_y) + 1);
    for (int sy = sy0; sy <= sy1; ++sy)
      for (int sx = sx0; sx <= sx1; ++sx)
        for (std::uint32_t i : bucket_[static_cast<std::size_t>(sy * p_.sectors_x + sx)])
          if (overlaps(statics_[i])) f(statics_[i]);
  }
  const std::size_t n = n_.load(std::memory_order_acquire);
  for (std::size_t i = 0; i < n; ++i) {
    const Entry& d = chunks_[i / kChunk][i % kChunk];
    if (overlaps(d)) f(d);
  }
}

std::uint32_t DecalLayer::count(double texel_m, double x0, double y0, double x1, double y1) const {
  std::uint32_t n = 0;
  for_each(texel_m, x0, y0, x1, y1, [&](const Entry&) { ++n; });
  return n;
}

std::uint32_t DecalLayer::count(double texel_m, double x0, double y0, double x1, double y1, std::uint64_t& texels) const {
  const int nx = static_cast<int>(std::llround((x1 - x0) / texel_m)), ny = static_cast<int>(std::llround((y1 - y0) / texel_m));
  std::uint32_t k = 0;
  texels = 0;
  for_each(texel_m, x0, y0, x1, y1, [&](const Entry& d) {
    ++k;
    texels += decal_span(Decal{d.x - d.half, d.y - d.half, d.x + d.half, d.y + d.half, d.rgba}, texel_m, x0, y0, nx, ny).texels();
  });
  return k;
}

void DecalLayer::collect(double texel_m, double x0, double y0, double x1, double y1, std::vector<Decal>& out) const {
  for_each(texel_m, x0, y0, x1, y1, [&](const Entry& d) { out.push_back(Decal{d.x - d.half, d.y - d.half, d.x + d.half, d.y + d.half, d.rgba}); });
}

}  // namespace vtsim::produce
