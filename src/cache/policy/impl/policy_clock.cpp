// CLOCK, second chance (Corbató, "A paging experiment with the Multics system", MIT Project MAC
// report MAC-M-384, 1968): cached keys sit on a ring with a reference bit each; a hit sets the
// bit; evict() sweeps the hand, clearing set bits and passing those keys over, and takes the first
// key whose bit is clear. A key enters with its bit clear, just behind the hand (the last place
// the sweep reaches), as in libCacheSim's Clock and FIFO-Reinsertion: the bit records a
// re-reference since admission. (Setting it at admission would let a scan clear every bit in one
// sweep and degenerate to FIFO.)
//
// The ring is a circular doubly linked list over a node slab (node_lists.h) indexed through a PageMap, so
// remove() of any key is O(1). Complexity: admit, hit, remove O(1) expected; evict O(1) amortised
// (each bit it clears was set by one hit) plus O(pinned keys passed), at most two revolutions.
// Memory: 16 bytes per node + 2-4 PageMap slots of 16 bytes. Sizes are not read (the owner
// weighs). Thread-safety: none.
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/node_lists.h"

namespace vtsim {
namespace {

class PolicyClock final : public IReplacementPolicy {
 public:
  void admit(std::uint64_t key, std::uint64_t) override {
    if (!index_.contains(key)) insert_behind_hand(key);  // a cached key: the owner's error, ignored
  }
  void hit(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) nodes_[*n].ref = 1;
  }
  void remove(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      unlink(i);
      index_.erase(key);
    }
  }
  std::uint64_t evict(Pinned pinned) override {
    // After one revolution every unpinned bit is clear, so a second one finds a victim if any
    // unpinned key is cached.
    const std::size_t steps = 2 * index_.size();
    std::uint32_t n = hand_;
    for (std::size_t s = 0; s < steps; ++s, n = nodes_[n].next) {
      const std::uint64_t key = nodes_[n].key;
      if (pinned(key)) continue;
      if (nodes_[n].ref) {
        nodes_[n].ref = 0;
        continue;
      }
      hand_ = n;
      unlink(n);  // moves the hand to the next key
      index_.erase(key);
      return key;
    }
    return kNoKey;
  }
  // The victim returns where it was, under the hand, bit clear: the next sweep meets it first.
  void restore(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return;
    hand_ = insert_behind_hand(key);
  }
  void set_capacity(std::uint64_t) override {}
  std::uint64_t size() const override { return index_.size(); }

 private:
  static constexpr std::uint32_t kNil = ~std::uint32_t{0};
  struct Node {
    std::uint64_t key = kNoKey;
    std::uint32_t prev = kNil, next = kNil;
    // The reference bit; 32 bits wide only because the node is 16 bytes either way.
    std::uint32_t ref = 0;
  };

  std::uint32_t insert_behind_hand(std::uint64_t key) {
    const std::uint32_t n = nodes_.alloc(key);
    index_.put(key, n);
    Node& node = nodes_[n];
    node.ref = 0;
    if (hand_ == kNil) {
      node.prev = node.next = n;
      hand_ = n;
    } else {
      nodes_.insert_before(hand_, n);
    }
    return n;
  }
  // Takes n off the ring and frees it; a hand on n moves to the next key.
  void unlink(std::uint32_t n) {
    Node& node = nodes_[n];
    if (node.next == n) {
      hand_ = kNil;
    } else {
      nodes_.unlink(n);
      if (hand_ == n) hand_ = node.next;
    }
    nodes_.release(n);
  }

  NodeSlab<Node> nodes_;
  PageMap<std::uint32_t> index_;
  std::uint32_t hand_ = kNil;
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_clock(std::uint64_t) { return std::make_unique<PolicyClock>(); }

}  // namespace vtsim
