#pragma once
// The clipmap as a streaming system: windows follow the camera's ground point, needs are the
// non-resident tiles of the active levels' windows (pyramid first: coarse before fine), screen
// importance comes from the feedback, and look-ahead prefetch fetches the band the windows will
// enter (Yao 2007 §4-2). docs/clipmap.md.
#include <string_view>
#include <unordered_map>

#include "cache/clipmap.h"
#include "cache/vram_arena.h"
#include "stream/system/clipmap_backed.h"
#include "stream/system/feedback.h"
#include "stream/system/i_system.h"
#include "stream/system/system_caps.h"

namespace vtsim {

class ClipmapSystem final : public ClipmapBacked {
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
  // Its name in the table (run.system) and what it can do.
  static constexpr char kName[] = "clipmap";
  static constexpr SystemCaps kCaps{.clip_window = true};

  void begin_frame(const SystemFrame& f) override;
  void missing_bytes_by_level(std::vector<std::uint64_t>& out) const override;
  void emit_needs(std::vector<Need>& out) override;
  std::uint32_t throttled_needs() const override { return throttled_; }
  bool commit(TileKey key, int frame) override;
  bool accepts(TileKey key) const override { return cm_.accepts(key); }
  nlohmann::json stats_json() const override;
  std::uint64_t vram_thrash() const override { return thrash_; }
  std::uint64_t evicted_unsampled_bytes() const override;

  // Level-0 ground texel under a world position (floor; exact for positions relative to the origin).
  std::int64_t ground_u(double x_m) const;
  std::int64_t ground_v(double y_m) const;

 private:
  std::uint64_t importance(int level, std::int64_t x, std::int64_t y);

  SystemSetup s_;
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
