// FIFO: evict the key admitted longest ago; a hit changes nothing (Belady, "A study of replacement
// algorithms for a virtual-storage computer", IBM Systems Journal 1966, names it as the baseline;
// libCacheSim's FIFO.c is the same queue). A doubly linked list over a node slab indexed through
// a PageMap, so remove() of any key is O(1). Memory: 24 bytes per node + 2-4 PageMap slots of 16
// bytes. Sizes are not read (the owner weighs). Thread-safety: none.
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"

namespace vtsim {
namespace {

class PolicyFifo final : public IReplacementPolicy {
 public:
  void admit(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return;  // a cached key: the owner's error, ignored
    const std::uint32_t n = alloc(key);
    index_.put(key, n);
    link_after(0, n);  // the newest end
  }
  void hit(std::uint64_t) override {}
  void remove(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      unlink(i);
      release(i);
      index_.erase(key);
    }
  }
  std::uint64_t evict(Pinned pinned) override {
    for (std::uint32_t n = nodes_[0].prev; n != 0; n = nodes_[n].prev) {  // oldest first
      const std::uint64_t key = nodes_[n].key;
      if (pinned(key)) continue;
      unlink(n);
      release(n);
      index_.erase(key);
      return key;
    }
    return kNoKey;
  }
  // The victim returns to the old end: the next eviction meets it first, as if it had stayed.
  void restore(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return;
    const std::uint32_t n = alloc(key);
    index_.put(key, n);
    link_after(nodes_[0].prev, n);
  }
  void set_capacity(std::uint64_t) override {}
  std::uint64_t size() const override { return index_.size(); }

 private:
  struct Node {
    std::uint64_t key = kNoKey;
    std::uint32_t prev = 0, next = 0;  // prev: towards the newest; node 0, the sentinel: next newest, prev oldest
  };
  std::uint32_t alloc(std::uint64_t key) {
    std::uint32_t n;
    if (!free_.empty()) {
      n = free_.back();
      free_.pop_back();
    } else {
      n = static_cast<std::uint32_t>(nodes_.size());
      nodes_.emplace_back();
    }
    nodes_[n].key = key;
    return n;
  }
  void release(std::uint32_t n) {
    nodes_[n].key = kNoKey;
    free_.push_back(n);
  }
  void unlink(std::uint32_t n) {
    nodes_[nodes_[n].prev].next = nodes_[n].next;
    nodes_[nodes_[n].next].prev = nodes_[n].prev;
  }
  // Links n between p and p's next, i.e. just older than p (p = 0, the sentinel: the newest).
  void link_after(std::uint32_t p, std::uint32_t n) {
    nodes_[n].prev = p;
    nodes_[n].next = nodes_[p].next;
    nodes_[nodes_[p].next].prev = n;
    nodes_[p].next = n;
  }

  std::vector<Node> nodes_ = std::vector<Node>(1);
  std::vector<std::uint32_t> free_;
  PageMap<std::uint32_t> index_;
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_fifo(std::uint64_t) { return std::make_unique<PolicyFifo>(); }

}  // namespace vtsim
