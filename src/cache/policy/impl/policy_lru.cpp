// LRU: evict the least recently requested key (Mattson, Gecsei, Slutz and Traiger, "Evaluation
// techniques for storage hierarchies", IBM Systems Journal 1970). A doubly linked list over a node
// slab (node_lists.h) indexed through a PageMap. Memory: 24 bytes per node + 2-4 PageMap slots of
// 16 bytes.
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/node_lists.h"

namespace vtsim {
namespace {

class PolicyLru final : public IReplacementPolicy {
 public:
  void admit(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return hit(key);  // a contract breach by the owner: keep the list whole
    const std::uint32_t n = nodes_.alloc(key);
    index_.put(key, n);
    nodes_.insert_after(0, n);
  }
  void hit(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      nodes_.unlink(*n);
      nodes_.insert_after(0, *n);
    }
  }
  void remove(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      nodes_.unlink(i);
      nodes_.release(i);
      index_.erase(key);
    }
  }
  std::uint64_t evict(Pinned pinned) override {
    for (std::uint32_t n = nodes_[0].prev; n != 0; n = nodes_[n].prev) {
      const std::uint64_t key = nodes_[n].key;
      if (pinned(key)) continue;
      nodes_.unlink(n);
      nodes_.release(n);
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
  NodeSlab<Node> nodes_{1};
  PageMap<std::uint32_t> index_;
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_lru(std::uint64_t) { return std::make_unique<PolicyLru>(); }

}  // namespace vtsim
