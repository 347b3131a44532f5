// FIFO: evict the key admitted longest ago; a hit changes nothing (Belady, "A study of replacement
// algorithms for a virtual-storage computer", IBM Systems Journal 1966, names it as the baseline;
// libCacheSim's FIFO.c is the same queue). One list of the shared node slab (node_lists.h: the
// sentinel's next is the newest, its prev the oldest) indexed through a PageMap, so remove() of any
// key is O(1). Memory: 24 bytes per node + 2-4 PageMap slots of 16
// bytes. Sizes are not read (the owner weighs). Thread-safety: none.
#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/node_lists.h"

namespace vtsim {
namespace {

class PolicyFifo final : public IReplacementPolicy {
 public:
  void admit(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return;  // a cached key: the owner's error, ignored
    const std::uint32_t n = nodes_.alloc(key);
    index_.put(key, n);
    nodes_.insert_after(0, n);  // the newest end
  }
  void hit(std::uint64_t) override {}
  void remove(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      nodes_.unlink(i);
      nodes_.release(i);
      index_.erase(key);
    }
  }
  std::uint64_t evict(Pinned pinned) override {
    for (std::uint32_t n = nodes_[0].prev; n != 0; n = nodes_[n].prev) {  // oldest first
      const std::uint64_t key = nodes_[n].key;
      if (pinned(key)) continue;
      nodes_.unlink(n);
      nodes_.release(n);
      index_.erase(key);
      return key;
    }
    return kNoKey;
  }
  // The victim returns to the old end: the next eviction meets it first, as if it had stayed.
  void restore(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return;
    const std::uint32_t n = nodes_.alloc(key);
    index_.put(key, n);
    nodes_.insert_after(nodes_[0].prev, n);
  }
  void set_capacity(std::uint64_t) override {}
  std::uint64_t size() const override { return index_.size(); }

 private:
  struct Node {
    std::uint64_t key = kNoKey;
    std::uint32_t prev = 0, next = 0;  // prev: towards the newest; node 0, the sentinel: next newest, prev oldest
  };
  NodeSlab<Node> nodes_{1};  // node 0: the sentinel
  PageMap<std::uint32_t> index_;
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_fifo(std::uint64_t) { return std::make_unique<PolicyFifo>(); }

}  // namespace vtsim
