#pragma once
// Four-double vectors for the renderers' batch arithmetic (plane and mesh resolve).
//
// An avx2 clone beside the default one, chosen at load by an ifunc resolver. TSan instruments the
// resolver, which then runs before the TSan runtime is up and crashes the binary at load (GCC 12),
// so the TSan build (VTSIM_NO_TARGET_CLONES, cmake/sanitizers.cmake) keeps the default code only.
#if defined(VTSIM_NO_TARGET_CLONES)
#define VTSIM_CLONES_AVX2
#else
#define VTSIM_CLONES_AVX2 __attribute__((target_clones("avx2", "default")))
#endif

#include <cstdint>

namespace vtsim::simd {

// Four doubles (GCC vector extension): one AVX register in the avx2 clones, two SSE2 registers
// otherwise. Every lane does exactly the scalar IEEE operations in the same order, and no clone
// enables FMA, so the values are the same bits whichever clone runs.
typedef double v4d __attribute__((vector_size(32)));
// A comparison of two v4d: per lane all ones (true) or zero.
typedef std::int64_t v4i __attribute__((vector_size(32)));

// By reference: a 32-byte vector passed or returned by value would change the ABI between the
// clones (-Wpsabi).
[[gnu::always_inline]] inline void load4(const double* p, v4d& v) { __builtin_memcpy(&v, p, sizeof v); }
[[gnu::always_inline]] inline void store4(double* p, const v4d& v) { __builtin_memcpy(p, &v, sizeof v); }

}  // namespace vtsim::simd
