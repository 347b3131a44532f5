#pragma once
// Pop-in measurement over the screen samples of a feedback buffer (BRIEF §5, docs/view.md):
// desired level d = desired_level(lod), resident level r = what the screen would sample given
// the streaming system's residency, deficit r − d.
#include <cstdint>
#include <vector>

#include "cache/i_residency.h"
#include "core/view.h"
#include "core/view_spans.h"

namespace vtsim {

struct PopinFrame {
  std::uint64_t samples = 0;      // samples in the buffer
  std::uint64_t blurry = 0;       // samples with deficit r − d >= 1 (sampled coarser than desired)
  double blurry_fraction = 0.0;   // blurry / samples; 0 when there are no samples
  double mean_deficit = 0.0;      // mean over samples of max(0, r − d), levels; 0 without samples
  std::uint64_t visible_pops = 0; // samples whose level after this frame's commits is >= 1 finer
                                  // than before them (r_now <= r_before − 1); 0 without "before"
};

// levels[i] = residency.resident_level(u, v, desired_level(lod, num_levels())) for sample i;
// levels is resized to the sample count (no reallocation once large enough).
// Throws std::invalid_argument when residency.num_levels() is outside [1, 127] (int8 levels) or
// it returns a level outside [0, num_levels()].
void resident_levels(const ViewBuffer& vb, const IResidency& residency, std::vector<std::int8_t>& levels);

// Pop-in statistics of one frame. levels_now: resident levels after this frame's commits;
// levels_before (optional): the same samples evaluated against the residency before them, for
// visible pops. A resident level of num_levels ("nothing resident") counts with its full deficit.
// Throws std::invalid_argument when a levels vector's size differs from the sample count or
// num_levels is outside [1, 127].
PopinFrame popin_stats(const ViewBuffer& vb, const std::vector<std::int8_t>& levels_now,
                       const std::vector<std::int8_t>* levels_before, int num_levels);

// Resident levels of a span buffer's samples: per span one level when every sample resolves to
// it (IResidency::span_resident_levels), otherwise the span's samples are expanded and asked one
// by one (their levels go to `sample`, from `offset[i]`).
struct SpanLevels {
  std::vector<std::int8_t> span;       // per span: the level of all its samples, or −1: see `sample`
  std::vector<std::uint32_t> offset;   // per span with −1: index of its first sample's level in `sample`
  std::vector<std::int8_t> sample;     // per-sample levels of the spans marked −1
};

// The span form of resident_levels: the same levels (and side effects) for every sample, at
// O(spans) when the residency resolves spans. Storage of `out` is reused. Throws like
// resident_levels, and std::invalid_argument when residency.num_levels() exceeds sb.levels.
void resident_levels(const SpanBuffer& sb, const IResidency& residency, SpanLevels& out);

// The span form of popin_stats: the same PopinFrame as popin_stats over the spans' samples.
// Throws std::invalid_argument when a SpanLevels does not match the spans or num_levels is
// outside [1, 127].
PopinFrame popin_stats(const SpanBuffer& sb, const SpanLevels& now, const SpanLevels* before, int num_levels);

}  // namespace vtsim
