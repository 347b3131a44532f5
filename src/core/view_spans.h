#pragma once
// Run-length form of a feedback buffer (docs/view.md, "Spans"). Along a buffer row the surface
// under the samples changes slowly: on the plane the hit is a linear-fractional function of the
// column, so the desired level and the tile change at a few columns only. A span is a maximal
// run of consecutive samples of one row with the same desired level and the same
// 2^block_shift-texel block at that level; consumers that only need (level, tile) per sample
// (feedback aggregation, clipmap residency, pop-in counts) work per span instead of per sample,
// and ask for a span's samples (expand_span) only where a span straddles a boundary they care
// about (a window edge, a tile a non-power-of-two tile size splits).
//
// The per-sample ViewBuffer stays the reference: a SpanBuffer is, field for field, what
// spans_from_samples makes of render()'s buffer (tested exactly on random cameras).
#include <cstdint>
#include <vector>

#include "core/camera.h"
#include "core/view.h"

namespace vtsim {

struct SpanBuffer;

// What re-renders the samples of a span buffer's pixels when the buffer keeps spans only: the scene
// that rendered the frame (IScene, sim/view/scene.h, implements it). Thread-safe like IScene.
class ISampleSource {
 public:
  virtual ~ISampleSource() = default;
  // Appends the samples of the `count` buffer pixels from `pixel` (one row, every one a sample)
  // of the frame `sb` holds: exactly what rendering that frame per sample gives at those pixels.
  virtual void render_pixels(const SpanBuffer& sb, std::uint32_t pixel, std::uint32_t count,
                             std::vector<ViewSample>& out) const = 0;
};

struct ViewSpan {
  std::int64_t u_lo = 0, u_hi = 0;  // least and greatest level-0 texel u of the span's samples
  std::int64_t v_lo = 0, v_hi = 0;  // least and greatest level-0 texel v
  std::uint32_t pixel = 0;  // buffer pixel of the first sample; sample k is at pixel + k (same row)
  std::uint32_t count = 0;  // samples, >= 1
  std::uint32_t first = 0;  // index of the first sample in render()'s sample order
  std::int32_t level = 0;   // desired_level(lod, mip_level_count(scene texture)) of every sample
};

struct SpanBuffer {
  // Set by the caller before rendering.
  int block_shift = 7;        // spans never cross a 2^block_shift-texel block of their level
                              // (7: one 128-texel tile); in [0, 62]
  bool keep_samples = false;  // also fill `view` with the per-sample buffer

  // Filled by IScene::render_spans.
  int width = 0, height = 0;  // feedback buffer size, pixels
  int divisor = 1;
  int levels = 1;  // mip_level_count of the scene's texture: spans' levels are clamped below it
  std::vector<ViewSpan> spans;  // pixel order
  std::uint64_t samples = 0;    // sum of the spans' counts
  ViewCounters counters;        // as render()'s
  bool has_samples = false;     // `view` holds this frame's samples (keep_samples, or a scene
                                // without a span renderer)
  ViewBuffer view;
  // What expand_span re-renders from when has_samples is false.
  const ISampleSource* scene = nullptr;
  Camera cam;
  ViewParams params;
  std::vector<std::uint32_t> surface;  // per buffer pixel, the scene's surface there (mesh: the
                                       // triangle), for scenes whose render_pixels needs it
};

// Appends span s's samples to `out`: exactly render()'s samples at those pixels (copied from
// `view` or recomputed by the scene). O(s.count).
void expand_span(const SpanBuffer& sb, const ViewSpan& s, std::vector<ViewSample>& out);

// Appends the samples of spans [begin, end) of sb in order: exactly render()'s samples at their
// pixels, as expand_span of each, with one scene call per row segment of adjacent spans (a face's
// coefficients are computed once per segment, not per span). O(samples).
void expand_spans(const SpanBuffer& sb, std::size_t begin, std::size_t end, std::vector<ViewSample>& out);

// Fills sb.view with the frame's samples (every span expanded) and sets has_samples, so that later
// expansions copy. No-op when has_samples is already set. O(samples).
void materialise_samples(SpanBuffer& sb);

// The spans of a per-sample buffer (the reference definition). `out` is cleared first; its
// storage is reused. `num_levels` = mip_level_count of the scene's texture. Throws
// std::invalid_argument for block_shift outside [0, 62] or num_levels outside [1, 64].
void spans_from_samples(const ViewBuffer& vb, int num_levels, int block_shift, std::vector<ViewSpan>& out);

// Throws std::invalid_argument unless block_shift is in [0, 62].
void check_block_shift(int block_shift);

// Finest desired level of any span, clamped to num_levels − 1; num_levels when there is none.
int finest_level(const SpanBuffer& sb, int num_levels);

}  // namespace vtsim
