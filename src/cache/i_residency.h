#pragma once
// The question pop-in measurement asks a streaming system: which level would the screen sample
// for this texel right now? Clipmaps answer from their valid windows, virtual textures from the
// page table's fallback; both apply the MaxTextureLOD clamp.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/view.h"
#include "core/view_spans.h"

namespace vtsim {

// 128 bits that identify a residency's state (IResidency::fingerprint).
struct ResidencyFingerprint {
  std::uint64_t a = 0, b = 0;
  bool operator==(const ResidencyFingerprint&) const = default;
};

class IResidency {
 public:
  virtual ~IResidency() = default;
  // Finest level >= desired_level the screen would sample at level-0 texel (u, v) given what is
  // resident (and any throttle clamp). Returns num_levels() when nothing covering it is resident.
  virtual int resident_level(std::int64_t u, std::int64_t v, int desired_level) const = 0;
  virtual int num_levels() const = 0;
  // Batch form over feedback samples: out[i] = resident_level(s[i].u, s[i].v,
  // desired_level(s[i].lod, num_levels())). Systems override it with a faster loop.
  virtual void resident_levels(const ViewSample* s, std::size_t n, std::int8_t* out) const {
    const int levels = num_levels();
    for (std::size_t i = 0; i < n; ++i)
      out[i] = static_cast<std::int8_t>(resident_level(s[i].u, s[i].v, desired_level(s[i].lod, levels)));
  }
  // Span form (view_spans.h): out[i] = the level every sample of span i resolves to (what
  // resident_levels gives each, with desired level min(span.level, num_levels() − 1), including
  // any side effect such as marking what is sampled), or −1 when the samples may differ or the
  // system cannot tell from the span's bounding box; the caller then asks per sample. The
  // default answers −1 for every span.
  virtual void span_resident_levels(const ViewSpan* s, std::size_t n, std::int8_t* out) const {
    (void)s;
    for (std::size_t i = 0; i < n; ++i) out[i] = -1;
  }

  // Sharing answers between residencies in the same state (a lockstep sweep's runs: most configs
  // hold the same tiles most frames; sim/run/popin_share.h). fingerprint: true and an identity of
  // everything the three lookups above read (parameters, windows or page table, resident tiles,
  // clamp), kept up to date as the state changes, so that equal fingerprints give equal levels
  // for equal input. Two independent 64-bit Zobrist sums: a false match of two different states
  // has probability ~2^-128. False (the default): no fingerprint, nothing is shared.
  virtual bool fingerprint(ResidencyFingerprint& /*out*/) const { return false; }
  // The lookups' side effect, marking what is sampled, as data: while `out` is set, each mark a
  // lookup makes appends an id (duplicates possible); apply_marks makes the same marks on a
  // residency with the same fingerprint. Residencies without a fingerprint ignore both.
  virtual void record_marks(std::vector<std::uint64_t>* /*out*/) const {}
  virtual void apply_marks(const std::vector<std::uint64_t>& /*marks*/) const {}
};

}  // namespace vtsim
