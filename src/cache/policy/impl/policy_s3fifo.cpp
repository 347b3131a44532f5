// S3-FIFO (Yang, Zhang, Qiu, Yue and Vinayak, "FIFO queues are all you need for cache eviction",
// SOSP 2023): three FIFO queues. A missed key enters the small queue S, or the main queue M when
// the ghost queue G remembers it; a hit raises the key's frequency, capped at 3 (a 2-bit counter).
// Eviction from S: the oldest key moves to M if its frequency is above 1, otherwise it leaves into
// G. Eviction from M: the oldest key with frequency > 0 is reinserted at the head with its
// frequency decremented, one with 0 leaves (no ghost). Most objects are requested once
// ("one-hit wonders"): S filters them out after a short stay.
//
// Sizes in the owner's unit (bytes for RAM, 1 per page) weigh every queue. S holds 10% of the
// capacity (the paper's default; rounded down as in libCacheSim), M the rest; G remembers keys
// whose sizes add up to M's share (with unit sizes: as many keys as M holds when full, the
// paper's choice). The queue to evict from is libCacheSim's rule: M when it holds more than its
// share or S is empty, otherwise S. One victim per evict() call: when S's oldest keys move to M
// and push M over its share, the paper's EVICTM inside EVICTS happens at the owner's next call.
//
// Call order: the owner may call admit() before evicting for the key (as vtsim's simulator and
// LruCache do, with the key pinned) or after. While the keys held weigh more than the capacity,
// evict() knows it runs for the key admitted last: it leaves that key out of the queue weights and
// never picks it, so both orders choose the same victims (up to the corner case where the
// evictions would have pushed the incoming key out of G: admit() took it out of G before them).
//
// evict() passes over pinned keys, leaving them in place. restore(): a key that left S into G
// returns to S's tail with its frequency; one that left M (no ghost) to M's tail with frequency 0.
//
// Complexity: admit, hit, remove O(1) expected; evict O(1) amortised (each reinsertion spends one
// frequency step a hit paid for) plus O(pinned keys passed), each passed at most 4 times.
// Memory: 32 bytes per node (cached and ghost keys alike) + 2-4 PageMap slots of 16 bytes.
// Thread-safety: none.
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/node_lists.h"

namespace vtsim {
namespace {

class PolicyS3Fifo final : public IReplacementPolicy {
 public:
  explicit PolicyS3Fifo(std::uint64_t capacity) { set_capacity(capacity); }

  void admit(std::uint64_t key, std::uint64_t size) override {
    std::uint32_t n;
    if (const std::uint32_t* g = index_.find(key)) {
      n = *g;
      if (nodes_[n].list != kGhost) return;  // already cached: the owner's error, ignored
      nodes_.unlink(n);
      nodes_.push_front(n, kMain, size);
    } else {
      n = alloc(key);
      nodes_.push_front(n, kSmall, size);
    }
    nodes_[n].freq = 0;
    incoming_ = n;
  }
  void hit(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      Node& node = nodes_[*n];
      // The paper's 2-bit counter: three hits are as good as more.
      if (node.list != kGhost && node.freq < 3) ++node.freq;
    }
  }
  void remove(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      if (nodes_[i].list == kGhost) return;
      nodes_.unlink(i);
      release(i);
      index_.erase(key);
    }
  }
  std::uint64_t evict(Pinned pinned) override {
    // While the keys held weigh more than the capacity the owner is making room for the key it
    // admitted last: leave it out of the weights and the candidates.
    std::uint32_t inc = kNil;
    if (incoming_ != kNil && nodes_[incoming_].list != kGhost && nodes_.weight(kSmall) + nodes_.weight(kMain) > capacity_)
      inc = incoming_;
    std::uint64_t w_small = nodes_.weight(kSmall), w_main = nodes_.weight(kMain);
    std::uint64_t n_small = nodes_.count(kSmall);
    if (inc != kNil) {
      (nodes_[inc].list == kSmall ? w_small : w_main) -= nodes_[inc].size;
      if (nodes_[inc].list == kSmall) --n_small;
    }
    std::uint64_t key = kNoKey;
    if (w_main > main_share_ || n_small == 0) {
      key = evict_main(pinned, inc);
      if (key == kNoKey) key = evict_small(pinned, inc);
    } else {
      key = evict_small(pinned, inc);
      if (key == kNoKey) key = evict_main(pinned, inc);
    }
    return key;
  }
  void restore(std::uint64_t key, std::uint64_t size) override {
    std::uint32_t n;
    std::uint8_t queue = kMain;
    if (const std::uint32_t* g = index_.find(key)) {
      n = *g;
      if (nodes_[n].list != kGhost) return;
      nodes_.unlink(n);
      queue = kSmall;  // only S's victims leave a ghost; it keeps the frequency it left with
    } else {
      n = alloc(key);
      nodes_[n].freq = 0;
    }
    nodes_.push_back(n, queue, size);
  }
  void set_capacity(std::uint64_t capacity) override {
    capacity_ = capacity;
    // 10%: the paper's small-queue share (§4, "S uses 10% of the cache space").
    small_share_ = capacity / 10;
    main_share_ = capacity - small_share_;
    trim_ghosts();
    incoming_ = kNil;
  }
  std::uint64_t size() const override { return nodes_.count(kSmall) + nodes_.count(kMain); }

 private:
  static constexpr std::uint32_t kNil = ~std::uint32_t{0};
  static constexpr std::uint8_t kSmall = 0, kMain = 1, kGhost = 2;  // also the sentinels' nodes
  struct Node {
    std::uint64_t key = kNoKey;
    std::uint64_t size = 0;
    std::uint32_t prev = 0, next = 0;  // towards the head (newest) / the tail (oldest)
    std::uint8_t freq = 0;
    std::uint8_t list = 0;  // its queue
  };

  // S's oldest keys: frequency > 1 moves to M (no victim yet), otherwise the key leaves into G.
  std::uint64_t evict_small(Pinned pinned, std::uint32_t inc) {
    for (std::uint32_t n = nodes_.back(kSmall); n != kSmall;) {
      const std::uint32_t towards_head = nodes_[n].prev;
      if (n == inc || pinned(nodes_[n].key)) {
        n = towards_head;
        continue;
      }
      const std::uint64_t size = nodes_[n].size;
      nodes_.unlink(n);
      if (nodes_[n].freq > 1) {
        nodes_.push_front(n, kMain, size);
        n = towards_head;
        continue;
      }
      const std::uint64_t key = nodes_[n].key;
      if (size <= main_share_) {
        nodes_.push_front(n, kGhost, size);
        trim_ghosts();
      } else {
        release(n);
        index_.erase(key);
      }
      return key;
    }
    return kNoKey;
  }
  // M's oldest keys: frequency > 0 goes back to the head one lower, 0 leaves. Keys moved to the
  // head are met again at the end of the walk; a walk that met no unpinned key ends it.
  std::uint64_t evict_main(Pinned pinned, std::uint32_t inc) {
    bool unpinned_seen = false;
    for (std::uint32_t n = nodes_.back(kMain);;) {
      if (n == kMain) {
        if (!unpinned_seen) return kNoKey;
        unpinned_seen = false;
        n = nodes_.back(kMain);
        continue;
      }
      const std::uint32_t towards_head = nodes_[n].prev;
      if (n == inc || pinned(nodes_[n].key)) {
        n = towards_head;
        continue;
      }
      unpinned_seen = true;
      Node& node = nodes_[n];
      const std::uint64_t size = node.size;
      nodes_.unlink(n);
      if (node.freq > 0) {
        --node.freq;
        nodes_.push_front(n, kMain, size);
        n = towards_head;
        continue;
      }
      const std::uint64_t key = node.key;
      release(n);
      index_.erase(key);
      return key;
    }
  }

  // G keeps the newest keys that weigh at most M's share.
  void trim_ghosts() {
    while (nodes_.weight(kGhost) > main_share_) {
      const std::uint32_t n = nodes_.back(kGhost);
      const std::uint64_t key = nodes_[n].key;
      nodes_.unlink(n);
      release(n);
      index_.erase(key);
    }
  }

  std::uint32_t alloc(std::uint64_t key) {
    const std::uint32_t n = nodes_.alloc(key);
    index_.put(key, n);
    return n;
  }
  void release(std::uint32_t n) {
    if (n == incoming_) incoming_ = kNil;
    nodes_.release(n);
  }

  // Nodes 0-2: the sentinels of S, M and G (next: head, newest; prev: tail, oldest).
  WeightedLists<Node, 3> nodes_;  // node_lists.h: each queue's weight (in the owner's unit) and key count
  PageMap<std::uint32_t> index_;  // cached and ghost keys
  std::uint64_t capacity_ = 0, small_share_ = 0, main_share_ = 0;
  std::uint32_t incoming_ = kNil;  // the node admitted last (see evict)
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_s3fifo(std::uint64_t capacity) {
  return std::make_unique<PolicyS3Fifo>(capacity);
}

}  // namespace vtsim
