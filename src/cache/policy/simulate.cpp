#include "cache/policy/simulate.h"

#include <stdexcept>
#include <string>

#include "cache/page_map.h"

namespace vtsim {

namespace {

bool simulate_is_incoming(const void* ctx, std::uint64_t key) { return key == *static_cast<const std::uint64_t*>(ctx); }

}  // namespace

SimStats simulate(std::span<const Access> accesses, IReplacementPolicy& policy, std::uint64_t capacity,
                  std::vector<std::uint64_t>* evicted) {
  if (capacity > kMaxPolicyCapacity)
    throw std::invalid_argument("simulate: capacity " + std::to_string(capacity) + " is above 2^62");
  SimStats st;
  PageMap<std::uint64_t> held;  // key -> size charged
  std::uint64_t held_bytes = 0;
  std::uint64_t incoming = kNoKey;
  const Pinned pin_incoming{simulate_is_incoming, &incoming};
  for (std::size_t i = 0; i < accesses.size(); ++i) {
    const Access a = accesses[i];
    if (a.key == kNoKey) throw std::invalid_argument("simulate: access " + std::to_string(i) + " has the reserved key ~0");
    ++st.requests;
    if (held.find(a.key)) {
      ++st.hits;
      policy.hit(a.key);
      continue;
    }
    ++st.misses;
    st.bytes_missed += a.size;
    if (a.size > capacity) {
      ++st.rejected;
      continue;
    }
    policy.admit(a.key, a.size);
    incoming = a.key;
    while (a.size > capacity - held_bytes) {
      const std::uint64_t v = policy.evict(pin_incoming);
      const std::uint64_t* s = v == kNoKey ? nullptr : held.find(v);
      if (s == nullptr || v == a.key)
        throw std::logic_error("simulate: the policy evicted no cached key while room was needed");
      held_bytes -= *s;
      held.erase(v);
      ++st.evictions;
      if (evicted) evicted->push_back(v);
    }
    held.put(a.key, a.size);
    held_bytes += a.size;
  }
  return st;
}

SimStats simulate(std::span<const Access> accesses, std::string_view policy, std::uint64_t capacity) {
  const auto p = make_replacement_policy(policy, capacity);
  return simulate(accesses, *p, capacity, nullptr);
}

}  // namespace vtsim
