#include "gl/gl_calibrate.h"

#include <epoxy/gl.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <random>
#include <stdexcept>

#include "core/error.h"
#include "core/tile_data.h"
#include "gl/gl_renderer.h"
#include "gl/gl_stream.h"

namespace vtsim::gl {

namespace {

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Levels of a virtual texture of `tile`-texel pages down to one page (StreamedVt's page table).
int page_levels(TextureExtent e, int tile) {
  int levels = 1;
  while (levels < 32 && std::max(e.width, e.height) >> (levels - 1) > tile) ++levels;
  return levels;
}

// One size's pages copied in frames of `batch` pages through StreamedVt; each frame's query read
// back after glFinish (StreamedVt::apply polls it).
class Batcher {
 public:
  Batcher(Renderer& r, int tile, int border, int channels, int slots, std::uint64_t seed) : vt_(r, tile, border, channels, slots, page_levels(r.texture(), tile)) {
    const auto side = static_cast<std::uint32_t>(tile + 2 * border);
    std::mt19937_64 rng(seed);
    for (int i = 0; i < slots; ++i) {
      auto d = std::make_unique<TileData>();
      d->key = TileKey(0, 0, i, 0);
      d->side = side;
      d->channels = static_cast<std::uint32_t>(channels);
      d->bytes = static_cast<std::size_t>(side) * side * static_cast<std::size_t>(channels);
      d->texels = std::make_unique<std::uint8_t[]>(d->bytes);
      for (std::size_t b = 0; b < d->bytes; b += 8) {
        const std::uint64_t x = rng();
        for (std::size_t k = 0; k < 8 && b + k < d->bytes; ++k) d->texels[b + k] = static_cast<std::uint8_t>(x >> (8 * k));
      }
      pages_.push_back(std::move(d));
    }
  }
  std::size_t page_bytes() const { return pages_.front()->bytes; }

  // One frame of `n` copies: (submit us, complete us, GPU us).
  void frame(int n, double& submit_us, double& complete_us, double& gpu_us) {
    const double ms0 = vt_.upload_gpu_ms();
    const std::uint64_t timed0 = vt_.timed_frames();
    const FrameUpdates none;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < n; ++i) {
      const TileData& d = *pages_[static_cast<std::size_t>(i)];
      vt_.upload(TileUpload{d.key, i, &d, nullptr});
    }
    vt_.apply(none);  // ends the frame's query
    const auto t1 = std::chrono::steady_clock::now();
    glFinish();
    const auto t2 = std::chrono::steady_clock::now();
    for (int tries = 0; vt_.timed_frames() == timed0; ++tries) {
      if (tries == 1000) throw std::runtime_error("gl calibrate-upload: the GL_TIME_ELAPSED query never completed");
      glFinish();
      vt_.apply(none);
    }
    if (vt_.timed_frames() != timed0 + 1) throw std::logic_error("gl calibrate-upload: more than one timed frame");
    submit_us = std::chrono::duration<double, std::micro>(t1 - t0).count();
    complete_us = std::chrono::duration<double, std::micro>(t2 - t0).count();
    gpu_us = (vt_.upload_gpu_ms() - ms0) * 1000.0;
  }

 private:
  StreamedVt vt_;
  std::vector<std::unique_ptr<TileData>> pages_;
};

}  // namespace

UploadCalibration calibrate_upload(Renderer& r, const UploadCalibrateOptions& o, const UploadProgress& progress) {
  if (o.tile < 1 || o.border < 0 || o.channels < 1 || o.channels > 4)
    throw InputError("--store", fmt::format("page geometry: tile {}, border {}, channels {}", o.tile, o.border, o.channels));
  if (o.reps < 1 || o.reps > 1000) throw InputError("--reps", fmt::format("{} (must be in 1..1000)", o.reps));
  if (o.batches.empty()) throw InputError("--batches", "no batch size");
  for (const int b : o.batches)
    if (b < 1 || b > 4096) throw InputError("--batches", fmt::format("{} pages a frame (must be in 1..4096)", b));
  std::vector<int> tiles = o.tiles;
  if (tiles.empty()) tiles = {std::max(1, o.tile / 2), o.tile, 2 * o.tile};
  for (const int t : tiles)
    if (t < 1 || t > 8192) throw InputError("--tiles", fmt::format("{} texels (must be in 1..8192)", t));
  const int slots = *std::max_element(o.batches.begin(), o.batches.end());
  for (const int t : tiles) {
    const auto side = static_cast<std::uint64_t>(t + 2 * o.border);
    if (side * side * static_cast<std::uint64_t>(o.channels) * static_cast<std::uint64_t>(slots) > (std::uint64_t{1} << 29))
      throw InputError("--tiles", fmt::format("{} pages of {}+2x{} texels a frame are over 512 MiB: fewer or smaller", slots, t, o.border));
  }
  UploadCalibration c;
  std::uint64_t seed = o.seed;
  for (const int tile : tiles) {
    if (progress) progress(fmt::format("pages of {}+2x{} texels, {} channels", tile, o.border, o.channels));
    Batcher b(r, tile, o.border, o.channels, slots, seed++);
    double s = 0, cpl = 0, g = 0;
    b.frame(slots, s, cpl, g);  // warm-up: the page table's first build, the ring's buffers, the driver's paths
    b.frame(slots, s, cpl, g);
    std::vector<std::vector<double>> sub(o.batches.size()), com(o.batches.size()), gpu(o.batches.size());
    for (int rep = 0; rep < o.reps; ++rep)
      for (std::size_t i = 0; i < o.batches.size(); ++i) {
        b.frame(o.batches[i], s, cpl, g);
        sub[i].push_back(s);
        com[i].push_back(cpl);
        gpu[i].push_back(g);
      }
    for (std::size_t i = 0; i < o.batches.size(); ++i) {
      UploadPoint p;
      p.tile = tile;
      p.border = o.border;
      p.channels = o.channels;
      p.bytes = b.page_bytes();
      p.batch = o.batches[i];
      p.reps = o.reps;
      p.submit_us = median_of(sub[i]);
      p.complete_us = median_of(com[i]);
      p.gpu_us = median_of(gpu[i]);
      c.points.push_back(p);
      // Relative error: each point's per-page time squared in the weight (a 200 KB page's
      // microseconds would outweigh a 15 KB one's); the store's own page, what the client copies, 4x.
      const double w = tile == o.tile ? 4.0 : 1.0;
      const auto rel = [&](double us) { return us > 0 ? w / ((us / p.batch) * (us / p.batch)) : w; };
      c.gpu_samples.push_back({p.bytes, p.batch, p.gpu_us, rel(p.gpu_us)});
      c.cpu_samples.push_back({p.bytes, p.batch, p.complete_us, rel(p.complete_us)});
    }
  }
  const UploadPoint& big = *std::max_element(c.points.begin(), c.points.end(),
                                              [](const UploadPoint& x, const UploadPoint& y) { return x.complete_us < y.complete_us; });
  c.gpu_saw_copies = big.gpu_us >= 0.1 * big.complete_us;
  c.gpu = fit_upload_model(c.gpu_samples);
  c.cpu = fit_upload_model(c.cpu_samples);
  return c;
}

}  // namespace vtsim::gl
