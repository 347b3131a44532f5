#pragma once
// The terrain's decals (VT Terrain Design: "decals such as footprints and damage are rendered into the
// levels too"), shared by the streaming system and the real clock's producer threads:
//  - seeded static decals, immutable after the constructor, bucketed by the sector holding their
//    centre (TerrainConfig::decals_static, decal_size_m, decal_seed);
//  - footprints, appended by the system as the camera walks (an append-only log).
// The system counts the decals over a tile for the cost model (count); the producer draws the same
// ones (collect), with the compositor's coverage rule (compositor.h, Decal).
//
// Thread-safety: one writer (add_footprint), any number of readers (count, collect, sizes) at once.
// add_footprint fills the entry, then publishes the new length with a release store; readers load
// it with acquire, so a reader sees a prefix of the log and never a torn entry. Entries live in
// fixed chunks that never move: nothing a reader holds is invalidated by a later add.
// Complexity: count and collect O(static decals in the sectors around the rectangle + footprints).
// Capacity: kMaxFootprints; beyond it add_footprint returns false and the caller counts the loss.
#include <atomic>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "stream/produce/compositor.h"

namespace vtsim::produce {

struct DecalLayerParams {
  int sectors_x = 16, sectors_y = 16;  // sectors (TerrainConfig)
  double sector_m = 512;               // sector side, m
  int statics = 4096;                  // seeded static decals over the whole terrain
  double static_size_m = 4;            // their side, m
  std::int64_t seed = 2;               // their positions' and colours' seed
  double footprint_size_m = 0.3;       // a footprint's side, m
};

class DecalLayer {
 public:
  static constexpr std::size_t kChunk = 4096;
  static constexpr std::size_t kMaxFootprints = kChunk * 1024;  // ~3,000 km of walk at one per 0.75 m

  explicit DecalLayer(const DecalLayerParams& p);

  // Writer only. A footprint centred at (x, y) m from the texture's origin; false when full.
  bool add_footprint(double x_m, double y_m);

  std::size_t statics() const { return statics_.size(); }
  std::size_t footprints() const { return n_.load(std::memory_order_acquire); }

  // Decals drawn into texels of texel_m over the rectangle [x0, x1) × [y0, y1), m: at least a
  // texel wide and overlapping it (TerrainSystem's rule, on centre ± half side).
  std::uint32_t count(double texel_m, double x0, double y0, double x1, double y1) const;
  // The same count, and the texels they touch summed over them (decal_span over the rectangle's
  // texels, as count_work counts them for the compositor).
  std::uint32_t count(double texel_m, double x0, double y0, double x1, double y1, std::uint64_t& texels) const;
  // The same decals as rectangles with their colours appended to `out` (statics by sector, then
  // footprints in the order placed): what the compositor draws, in that order.
  void collect(double texel_m, double x0, double y0, double x1, double y1, std::vector<Decal>& out) const;

 private:
  struct Entry {
    double x, y, half;  // centre from the texture's origin, half side, m
    std::array<std::uint8_t, 4> rgba;
  };
  template <class F>
  void for_each(double texel_m, double x0, double y0, double x1, double y1, F&& f) const;

  DecalLayerParams p_;
  std::vector<Entry> statics_;
  std::vector<std::vector<std::uint32_t>> bucket_;  // per sector: statics whose centre lies in it
  std::array<std::unique_ptr<Entry[]>, kMaxFootprints / kChunk> chunks_;
  std::atomic<std::size_t> n_{0};
};

}  // namespace vtsim::produce
