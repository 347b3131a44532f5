#include "core/view_spans.h"

#include <algorithm>
#include <stdexcept>

namespace vtsim {

void check_block_shift(int block_shift) {
  if (block_shift < 0 || block_shift > 62) throw std::invalid_argument("spans: block_shift must be in [0, 62]");
}

void expand_span(const SpanBuffer& sb, const ViewSpan& s, std::vector<ViewSample>& out) {
  if (sb.has_samples) {
    const auto b = sb.view.samples.begin() + static_cast<std::ptrdiff_t>(s.first);
    out.insert(out.end(), b, b + static_cast<std::ptrdiff_t>(s.count));
    return;
  }
  if (!sb.scene) throw std::logic_error("expand_span: the span buffer has neither samples nor a scene");
  sb.scene->render_pixels(sb, s.pixel, s.count, out);
}

void expand_spans(const SpanBuffer& sb, std::size_t begin, std::size_t end, std::vector<ViewSample>& out) {
  if (begin >= end) return;
  if (end > sb.spans.size()) throw std::invalid_argument("expand_spans: span range beyond the buffer");
  if (sb.has_samples) {  // spans cover consecutive samples in order
    const auto b = sb.view.samples.begin() + static_cast<std::ptrdiff_t>(sb.spans[begin].first);
    const ViewSpan& last = sb.spans[end - 1];
    out.insert(out.end(), b, sb.view.samples.begin() + static_cast<std::ptrdiff_t>(last.first + last.count));
    return;
  }
  if (!sb.scene) throw std::logic_error("expand_spans: the span buffer has neither samples nor a scene");
  const std::uint32_t w = static_cast<std::uint32_t>(sb.width > 0 ? sb.width : 1);
  for (std::size_t i = begin; i < end;) {
    const std::uint32_t pixel = sb.spans[i].pixel;
    std::uint32_t count = sb.spans[i].count;
    std::size_t j = i + 1;
    while (j < end && sb.spans[j].pixel == pixel + count && sb.spans[j].pixel / w == pixel / w) count += sb.spans[j++].count;
    sb.scene->render_pixels(sb, pixel, count, out);
    i = j;
  }
}

void materialise_samples(SpanBuffer& sb) {
  if (sb.has_samples) return;
  sb.view.samples.clear();
  expand_spans(sb, 0, sb.spans.size(), sb.view.samples);
  sb.view.width = sb.width;
  sb.view.height = sb.height;
  sb.view.divisor = sb.divisor;
  sb.view.counters = sb.counters;
  sb.has_samples = true;
}

void spans_from_samples(const ViewBuffer& vb, int num_levels, int block_shift, std::vector<ViewSpan>& out) {
  check_block_shift(block_shift);
  if (num_levels < 1 || num_levels > 64) throw std::invalid_argument("spans: num_levels must be in [1, 64]");
  out.clear();
  const std::uint32_t w = static_cast<std::uint32_t>(vb.width > 0 ? vb.width : 1);
  const ViewSample* const samples = vb.samples.data();
  const std::size_t n = vb.samples.size();
  if (n == 0) return;
  // The open span lives in locals and is appended when the next one starts.
  ViewSpan b{};
  std::int64_t bu = 0, bv = 0;  // its block at its level
  std::uint32_t next = 0;       // the pixel that would continue it
  std::uint32_t row_end = 0;    // first pixel of the row after its row (spans stay in a row)
  for (std::size_t i = 0; i < n; ++i) {
    const ViewSample& s = samples[i];
    const int level = desired_level(s.lod, num_levels);
    const int sh = level + block_shift;
    const std::int64_t su = sh < 63 ? s.u >> sh : 0, sv = sh < 63 ? s.v >> sh : 0;
    if (i > 0 && s.pixel == next && s.pixel < row_end && level == b.level && su == bu && sv == bv) {
      ++b.count;
      ++next;
      b.u_lo = s.u < b.u_lo ? s.u : b.u_lo;
      b.u_hi = s.u > b.u_hi ? s.u : b.u_hi;
      b.v_lo = s.v < b.v_lo ? s.v : b.v_lo;
      b.v_hi = s.v > b.v_hi ? s.v : b.v_hi;
      continue;
    }
    if (i > 0) out.push_back(b);
    b = ViewSpan{s.u, s.u, s.v, s.v, s.pixel, 1, static_cast<std::uint32_t>(i), level};
    bu = su;
    bv = sv;
    next = s.pixel + 1;
    row_end = static_cast<std::uint32_t>(std::min<std::uint64_t>((static_cast<std::uint64_t>(s.pixel / w) + 1) * w, 0xffffffffu));
  }
  out.push_back(b);
}

int finest_level(const SpanBuffer& sb, int num_levels) {
  int finest = num_levels;
  // From the last span: the bottom rows are the nearest ground, where level 0 usually is.
  for (auto it = sb.spans.rbegin(); it != sb.spans.rend() && finest > 0; ++it) {
    const int d = it->level < num_levels - 1 ? it->level : num_levels - 1;
    finest = d < finest ? d : finest;
  }
  return finest;
}

}  // namespace vtsim
