#pragma once
// Replacement policies: which cached block leaves when room is needed (docs/cache.md,
// "Replacement policies"). One interface serves the RAM tier (blocks weighted by bytes), the VT
// page pool (unit pages) and the offline simulator that replays a recorded access sequence. One
// policy per file in cache/policy/impl/, registered by one line in cache/policy/policy_registry.cpp.
//
// Division of labour: the owner holds key -> value, the bytes held and the capacity, and decides
// when room is needed; the policy holds only the order (and, for ARC and S3-FIFO, a bounded ghost
// history of keys it evicted). The owner calls:
//   admit(key, size)  a key not cached enters after a miss. Never for a key already cached.
//   hit(key)          a cached key was requested (a promoting lookup).
//   remove(key)       a cached key left for a reason of the owner's (erase, clear, replacement):
//                     no ghost entry. No-op for a key the policy does not hold.
//   evict(pinned)     choose a cached key that `pinned` does not protect, forget it (updating
//                     ghost history) and return it; kNoKey when every cached key is pinned or none
//                     is cached. The owner then removes the value.
//   restore(key, size) a key evict() returned was kept after all (the VT pool's pending victim
//                     rescued or released): it re-enters as if it had never left, as far as the
//                     policy can tell. Default: admit.
// Call order on a miss: admit the missed key, then evict() with it pinned until the sizes fit (as
// LruCache::insert and the offline simulator do). ARC's victim choice depends on which key missed,
// and it reads that from the order; S3-FIFO and ARC leave the just-admitted key out of their
// weights while they evict for it. The VT pool evicts first (a slot is reserved before the page
// arrives) and admits when the page completes: there ARC adapts its target one miss late.
// Sizes are in the owner's unit: bytes for RAM, 1 per page for the pool. `capacity` (same unit)
// is what the owner holds at most; policies that partition it (ARC, S3-FIFO) read it.
// Keys are 64-bit (TileKey::bits); kNoKey (all ones) is never a key.
//
// Complexity: admit, hit, remove O(1) expected; evict O(1) amortised plus O(pinned keys passed).
// Each implementation states its memory per key. Thread-safety: none (one owner).
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "core/registry.h"

namespace vtsim {

inline constexpr std::uint64_t kNoKey = ~std::uint64_t{0};

// Keys evict() must pass over (the pool: pages used this frame). A plain function pointer and a
// context, not std::function: evict() sits on the replay's hot path.
struct Pinned {
  bool (*fn)(const void* ctx, std::uint64_t key) = nullptr;
  const void* ctx = nullptr;
  bool operator()(std::uint64_t key) const { return fn != nullptr && fn(ctx, key); }
};

class IReplacementPolicy {
 public:
  virtual ~IReplacementPolicy() = default;
  virtual void admit(std::uint64_t key, std::uint64_t size) = 0;
  virtual void hit(std::uint64_t key) = 0;
  virtual void remove(std::uint64_t key) = 0;
  virtual std::uint64_t evict(Pinned pinned = {}) = 0;
  virtual void restore(std::uint64_t key, std::uint64_t size) { admit(key, size); }
  // The owner's capacity changed (RAM set_capacity): partitions rescale.
  virtual void set_capacity(std::uint64_t capacity) = 0;
  // Frame boundary (frame number rising by one per frame): policies that know frames read it.
  virtual void begin_frame(int /*frame*/) {}
  // Keys held (cached, ghosts excluded).
  virtual std::uint64_t size() const = 0;
};

struct ReplacementPolicyInfo {
  std::string_view name;
  std::string_view why;
  std::unique_ptr<IReplacementPolicy> (*make)(std::uint64_t capacity);
};

// The table (policy_registry.cpp): "lru", "clock", "s3fifo", "arc", ...
const Registry<ReplacementPolicyInfo>& replacement_policies();

// Throws std::invalid_argument (unknown name, with "did you mean") for a name not in the table.
std::unique_ptr<IReplacementPolicy> make_replacement_policy(std::string_view name, std::uint64_t capacity);

}  // namespace vtsim
