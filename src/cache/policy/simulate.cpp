#include "cache/policy/simulate.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "cache/page_map.h"

namespace vtsim {

namespace {

bool simulate_is_incoming(const void* ctx, std::uint64_t key) { return key == *static_cast<const std::uint64_t*>(ctx); }

struct SimFramePin {
  const PageMap<std::int64_t>* last_frame;  // key -> the last frame that requested it
  std::int64_t frame;
};
bool simulate_used_this_frame(const void* ctx, std::uint64_t key) {
  const auto* p = static_cast<const SimFramePin*>(ctx);
  const std::int64_t* f = p->last_frame->find(key);
  return f != nullptr && *f == p->frame;
}

}  // namespace

SimStats simulate(std::span<const Access> accesses, IReplacementPolicy& policy, std::uint64_t capacity,
                  std::vector<std::uint64_t>* evicted, MissOrder order) {
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
    const bool admit_first = order == MissOrder::kAdmitFirst;
    if (admit_first) policy.admit(a.key, a.size);
    incoming = admit_first ? a.key : kNoKey;
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
    if (!admit_first) policy.admit(a.key, a.size);
    held.put(a.key, a.size);
    held_bytes += a.size;
  }
  return st;
}

SimStats simulate_frames(std::span<const Access> accesses, std::span<const std::uint64_t> frame_start,
                         IReplacementPolicy& policy, std::uint64_t capacity) {
  if (capacity > kMaxPolicyCapacity)
    throw std::invalid_argument("simulate_frames: capacity " + std::to_string(capacity) + " is above 2^62");
  SimStats st;
  PageMap<std::uint64_t> held;
  PageMap<std::int64_t> last_frame;
  std::uint64_t held_bytes = 0;
  SimFramePin pin{&last_frame, -1};
  const Pinned pinned{simulate_used_this_frame, &pin};
  std::size_t next_frame = 0;
  for (std::size_t i = 0; i < accesses.size(); ++i) {
    // A frame starts: every key it requests is pinned for the whole frame, as the pool marks its
    // wanted pages used before it reserves slots for the missing ones.
    std::size_t frame_end = i;
    if (frame_start.empty()) {  // no frames: each access is one
      pin.frame = static_cast<std::int64_t>(i);
      policy.begin_frame(static_cast<int>(i));
      frame_end = i + 1;
    }
    while (next_frame < frame_start.size() && frame_start[next_frame] <= i) {
      pin.frame = static_cast<std::int64_t>(next_frame++);
      policy.begin_frame(static_cast<int>(pin.frame));
      frame_end = next_frame < frame_start.size() ? std::min<std::size_t>(frame_start[next_frame], accesses.size()) : accesses.size();
    }
    for (std::size_t j = i; j < frame_end; ++j) {
      if (accesses[j].key == kNoKey)
        throw std::invalid_argument("simulate_frames: access " + std::to_string(j) + " has the reserved key ~0");
      last_frame.put(accesses[j].key, pin.frame);
    }
    const Access a = accesses[i];
    ++st.requests;
    if (held.find(a.key) != nullptr) {
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
    bool room = true;
    while (a.size > capacity - held_bytes) {
      const std::uint64_t v = policy.evict(pinned);  // the missed key is pinned too: requested this frame
      if (v == kNoKey) {
        room = false;
        break;
      }
      const std::uint64_t* sz = held.find(v);
      if (sz == nullptr) throw std::logic_error("simulate_frames: the policy evicted a key it does not hold");
      held_bytes -= *sz;
      held.erase(v);
      ++st.evictions;
    }
    if (!room) {  // every cached key is in use this frame: the request goes without, as in the pool
      policy.remove(a.key);
      ++st.rejected;
      continue;
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
