#pragma once
// The clipmap as a streaming system: windows follow the camera's ground point, needs are the
// non-resident tiles of the active levels' windows (pyramid first: coarse before fine), screen
// importance comes from the feedback, and look-ahead prefetch fetches the band the windows will
// enter (Yao 2007 §4-2). docs/clipmap.md.
#include <string_view>
#include <unordered_map>

#include "cache/clipmap.h"
#include "cache/vram_arena.h"
#include "stream/system/feedback.h"
#include "stream/system/i_system.h"

namespace vtsim {

class ClipmapSystem final : public IStreamingSystem {
 public:
  ClipmapSystem(const SystemSetup& s, const ClipmapConfig& c);
  // What the systems' table (sim/run/systems.cpp) reads.
  using Config = ClipmapConfig;  // the config's [clipmap] section
  // The clipmap structure's parameters (cache/clipmap.h): the section plus the texture.
  static ClipmapParams params(const SystemSetup& s, const ClipmapConfig& c);
  // Cross-field checks; throws InputError("config", "field 'clipmap.clipsize': ...").
  static void validate(const SystemSetup& s, const ClipmapConfig& c, const ThrottleParams& throttle);
  // The levels a store must hold: every level down to 1×1 (the clipmap samples all of them).
  static int store_levels(const SystemSetup& s, const ClipmapConfig& c);
  static constexpr std::string_view kStoreLevels = "a clipmap samples every level down to 1×1";
  // The real clock's VRAM: every level's window of tile slots; the config field that sizes it.
  static VramArena vram_arena(const SystemSetup& s, const ClipmapConfig& c, std::vector<std::uint32_t> layer_bytes,
                              std::uint64_t host_limit);
  static constexpr std::string_view kVramField = "clipmap.clipsize";

  int num_levels() const override { return cm_.num_levels(); }
  int resident_level(std::int64_t u, std::int64_t v, int desired_level) const override {
    return cm_.resident_level(u, v, desired_level);
  }
  void resident_levels(const ViewSample* s, std::size_t n, std::int8_t* out) const override {
    cm_.resident_levels(s, n, out);
  }
  void span_resident_levels(const ViewSpan* s, std::size_t n, std::int8_t* out) const override {
    cm_.span_resident_levels(s, n, out);
  }
  bool uses_spans() const override { return true; }
  void begin_frame(const SystemFrame& f) override;
  void missing_bytes_by_level(std::vector<std::uint64_t>& out) const override;
  int coarsest_clamp() const override { return cm_.first_pyramid_level(); }
  void apply_throttle(const ThrottleDecision& d) override { cm_.set_clamp(d.clamp); }
  void emit_needs(std::vector<Need>& out) override;
  std::uint32_t throttled_needs() const override { return throttled_; }
  bool commit(TileKey key, int frame) override;
  bool accepts(TileKey key) const override { return cm_.accepts(key); }
  void clip_windows(std::vector<ClipWindow>& out) const override;
  void set_mark_sampled(bool on) override { cm_.set_mark_sampled(on); }
  bool fingerprint(ResidencyFingerprint& out) const override { return cm_.fingerprint(out); }
  void record_marks(std::vector<std::uint64_t>* out) const override { cm_.record_marks(out); }
  void apply_marks(const std::vector<std::uint64_t>& marks) const override { cm_.apply_marks(marks); }
  nlohmann::json stats_json() const override;
  std::uint64_t vram_evictions() const override { return cm_.stats().vram_evictions; }
  void record_vram_evictions(std::vector<TileKey>* log) override { evict_log_ = log; }
  int tile_sampled(TileKey key) const override { return cm_.sampled(key); }
  std::uint64_t vram_thrash() const override { return thrash_; }
  std::uint64_t evicted_unsampled_bytes() const override;

  const Clipmap& clipmap() const { return cm_; }
  // Level-0 ground texel under a world position (floor; exact for positions relative to the origin).
  std::int64_t ground_u(double x_m) const;
  std::int64_t ground_v(double y_m) const;

 private:
  std::uint64_t importance(int level, std::int64_t x, std::int64_t y);

  SystemSetup s_;
  Clipmap cm_;
  std::vector<TileKey>* evict_log_ = nullptr;  // record_vram_evictions
  std::int64_t gu_ = 0, gv_ = 0, fu_ = 0, fv_ = 0;
  bool prefetch_ = false;
  int finest_active_ = 0;
  int frame_ = 0;
  std::uint32_t throttled_ = 0;
  // This frame's feedback at the clipmap's tile size, sorted by key. Aggregated on the first
  // importance() call of the frame: only missing window tiles ask, and most frames of a walk
  // have none (the feedback is then never aggregated).
  std::vector<TileUse> uses_;
  const SpanBuffer* spans_ = nullptr;  // this frame's feedback (begin_frame)
  const ViewBuffer* view_ = nullptr;
  bool uses_ready_ = false;
  std::unordered_map<std::uint64_t, int> evicted_at_;  // (level, x, y) -> frame its slot was overwritten
  std::uint64_t thrash_ = 0;
};

}  // namespace vtsim
