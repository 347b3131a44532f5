#pragma once
// What the clipmap-backed streaming systems (the clipmap, and the terrain whose levels are
// produced) share: residency is the clip stack's (cache/clipmap.h), so the residency queries,
// the MaxTextureLOD clamp, the windows an engine mirrors and the render-ahead marks all forward
// to it. A derived system adds its needs, commits and statistics.
#include <cstdint>
#include <vector>

#include "cache/clipmap.h"
#include "stream/system/i_system.h"

namespace vtsim {

class ClipmapBacked : public IStreamingSystem {
 public:
  explicit ClipmapBacked(const ClipmapParams& p) : cm_(p) {}

  int num_levels() const override { return cm_.num_levels(); }
  int resident_level(std::int64_t u, std::int64_t v, int desired_level) const override {
    return cm_.resident_level(u, v, desired_level);
  }
  void resident_levels(const ViewSample* s, std::size_t n, std::int8_t* out) const override { cm_.resident_levels(s, n, out); }
  void span_resident_levels(const ViewSpan* s, std::size_t n, std::int8_t* out) const override {
    cm_.span_resident_levels(s, n, out);
  }
  bool uses_spans() const override { return true; }
  int coarsest_clamp() const override { return cm_.first_pyramid_level(); }
  void apply_throttle(const ThrottleDecision& d) override { cm_.set_clamp(d.clamp); }
  void clip_windows(std::vector<ClipWindow>& out) const override {
    out.clear();
    for (int l = 0; l < cm_.num_levels(); ++l) {
      const Clipmap::Window w = cm_.window(l);
      out.push_back({w.x0, w.y0, w.w, w.h});
    }
  }
  void set_mark_sampled(bool on) override { cm_.set_mark_sampled(on); }
  bool fingerprint(ResidencyFingerprint& out) const override { return cm_.fingerprint(out); }
  void record_marks(std::vector<std::uint64_t>* out) const override { cm_.record_marks(out); }
  void apply_marks(const std::vector<std::uint64_t>& marks) const override { cm_.apply_marks(marks); }
  std::uint64_t vram_evictions() const override { return cm_.stats().vram_evictions; }

  const Clipmap& clipmap() const { return cm_; }

 protected:
  Clipmap cm_;
};

}  // namespace vtsim
