// LRU: evict the least recently requested key (Mattson, Gecsei, Slutz and Traiger, "Evaluation
// techniques for storage hierarchies", IBM Systems Journal 1970). A doubly linked list over a node
// slab indexed through a PageMap. Memory: 24 bytes per node + 2-4 PageMap slots of 16 bytes.
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"

namespace vtsim {
namespace {

class PolicyLru final : public IReplacementPolicy {
 public:
  void admit(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return hit(key);  // a contract breach by the owner: keep the list whole
    const std::uint32_t n = alloc(key);
    index_.put(key, n);
    push_front(n);
  }
  void hit(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      unlink(*n);
      push_front(*n);
    }
  }
  void remove(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      unlink(i);
      release(i);
      index_.erase(key);
    }
  }
  std::uint64_t evict(Pinned pinned) override {
    for (std::uint32_t n = nodes_[0].prev; n != 0; n = nodes_[n].prev) {
      const std::uint64_t key = nodes_[n].key;
      if (pinned(key)) continue;
      unlink(n);
      release(n);
      index_.erase(key);
      return key;
    }
    return kNoKey;
  }
  void set_capacity(std::uint64_t) override {}
  std::uint64_t size() const override { return index_.size(); }

 private:
  struct Node {
    std::uint64_t key = kNoKey;
    std::uint32_t prev = 0, next = 0;  // node 0: the sentinel (next: most recent, prev: least)
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
  void push_front(std::uint32_t n) {
    nodes_[n].prev = 0;
    nodes_[n].next = nodes_[0].next;
    nodes_[nodes_[0].next].prev = n;
    nodes_[0].next = n;
  }

  std::vector<Node> nodes_ = std::vector<Node>(1);
  std::vector<std::uint32_t> free_;
  PageMap<std::uint32_t> index_;
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_lru(std::uint64_t) { return std::make_unique<PolicyLru>(); }

}  // namespace vtsim
