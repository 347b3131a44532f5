// ARC, adaptive replacement cache (Megiddo and Modha, "ARC: a self-tuning, low overhead
// replacement cache", FAST 2003, Fig. 4). Cached keys are in T1 (seen once recently) or T2 (seen
// at least twice); B1 and B2 remember keys recently evicted from T1 and T2 (ghosts). A hit moves
// the key to T2's MRU end (case I). A miss on a B1 ghost raises the target p for T1 (case II), on a
// B2 ghost lowers it (case III); either way the key enters T2. A miss on an unknown key enters T1
// after trimming the directories (case IV). REPLACE evicts T1's LRU key into B1 when T1 holds more
// than p (or exactly p and the missed key was a B2 ghost), T2's LRU key into B2 otherwise.
//
// Sizes: every list is weighed in the owner's unit (bytes for RAM, 1 per page) and p is in that
// unit. A ghost hit moves p by the key's size times the paper's ratio (max(1, |B2|/|B1|) for B1,
// max(1, |B1|/|B2|) for B2, list weights), so one ghost hit of an s-byte key counts like s unit
// ghost hits. Case IV's bounds read "does the new key fit": trim B1's LRU while
// |T1| + |B1| + size > c (the paper's |L1| = c), B2's while the whole directory + size > 2c (the
// paper's = 2c), and when T1 alone leaves no room (B1 empty, |T1| + size > c) evict T1's LRU keys
// without ghosts (case IV.A's "delete LRU page in T1"). B1 + B2 never exceed c: a ghost insertion
// that would exceed it drops B2's (else B1's) LRU ghosts. With unit sizes each of these is the
// paper's rule and the guard never fires: this is the paper's ARC.
//
// Owner-driven interface: REPLACE needs the missed key (its case sets p, and the B2 tie-break).
// admit() does the case analysis and places the key; evict() calls while the keys held weigh more
// than c then run REPLACE for that key, leaving it out of |T1| and out of the candidates. So an
// owner that admits before evicting (vtsim's simulator; LruCache's insert does the same) gets the
// paper's ARC. An owner that evicts first gets REPLACE with p as the previous miss left it and no
// B2 tie-break: ARC with p one miss late.
//
// evict() passes over pinned keys (if every key of the chosen list is pinned it takes the other
// list's). restore(): a key that left into B1 (B2) returns to T1's (T2's) LRU end; one that left
// without a ghost to T1's LRU end.
//
// Complexity: admit, hit, remove O(1) expected, amortised over the ghosts they trim; evict O(1)
// plus O(pinned keys passed). Memory: 32 bytes per node (cached and ghost keys alike, at most 2c
// in unit sizes) + 2-4 PageMap slots of 16 bytes. Thread-safety: none.
#include <algorithm>
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/node_lists.h"

namespace vtsim {
namespace {

class PolicyArc final : public IReplacementPolicy {
 public:
  explicit PolicyArc(std::uint64_t capacity) : c_(capacity) {}

  void admit(std::uint64_t key, std::uint64_t size) override {
    std::uint32_t n;
    from_b2_ = false;
    if (const std::uint32_t* g = index_.find(key)) {
      n = *g;
      const std::uint8_t list = nodes_[n].list;
      if (list == kT1 || list == kT2) return;  // already cached: the owner's error, ignored
      const double s = static_cast<double>(size);
      const double b1 = static_cast<double>(nodes_.weight(kB1)), b2 = static_cast<double>(nodes_.weight(kB2));
      if (list == kB1) {  // case II: T1 was too small
        p_ = std::min(static_cast<double>(c_), p_ + s * (b1 >= b2 || b1 == 0 ? 1.0 : b2 / b1));
      } else {  // case III: T2 was too small
        p_ = std::max(0.0, p_ - s * (b2 >= b1 || b2 == 0 ? 1.0 : b1 / b2));
        from_b2_ = true;
      }
      nodes_.unlink(n);
      nodes_.push_front(n, kT2, size);
    } else {  // case IV
      while (nodes_.weight(kT1) + nodes_.weight(kB1) + size > c_ && nodes_.count(kB1) > 0) drop_lru(kB1);
      if (nodes_.weight(kT1) + nodes_.weight(kB1) + size <= c_)
        while (nodes_.weight(kT1) + nodes_.weight(kT2) + nodes_.weight(kB1) + nodes_.weight(kB2) + size > 2 * c_ &&
               nodes_.count(kB2) > 0)
          drop_lru(kB2);
      n = alloc(key);
      nodes_.push_front(n, kT1, size);
    }
    incoming_ = n;
  }
  void hit(std::uint64_t key) override {  // case I
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      if (nodes_[i].list != kT1 && nodes_[i].list != kT2) return;
      const std::uint64_t size = nodes_[i].size;
      nodes_.unlink(i);
      nodes_.push_front(i, kT2, size);
    }
  }
  void remove(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      const std::uint32_t i = *n;
      if (nodes_[i].list != kT1 && nodes_[i].list != kT2) return;
      nodes_.unlink(i);
      release(i);
    }
  }
  std::uint64_t evict(Pinned pinned) override {
    // Over capacity: the owner is making room for the key it admitted last (see the header).
    std::uint32_t inc = kNil;
    if (incoming_ != kNil && nodes_.weight(kT1) + nodes_.weight(kT2) > c_) inc = incoming_;
    const bool inc_in_t1 = inc != kNil && nodes_[inc].list == kT1;
    const std::uint64_t t1 = nodes_.weight(kT1) - (inc_in_t1 ? nodes_[inc].size : 0);
    const std::uint64_t t1_keys = nodes_.count(kT1) - (inc_in_t1 ? 1 : 0);
    // Case IV.A with T1 full: its LRU key leaves without a ghost.
    if (inc_in_t1 && nodes_.count(kB1) == 0 && t1 + nodes_[inc].size > c_)
      if (const std::uint32_t v = lru_candidate(kT1, pinned, inc); v != kNil) {
        const std::uint64_t key = nodes_[v].key;
        nodes_.unlink(v);
        release(v);
        return key;
      }
    // REPLACE.
    const double t1d = static_cast<double>(t1);
    const bool b2_tie = inc != kNil && from_b2_ && t1d == p_;
    const bool from_t1 = t1_keys >= 1 && (b2_tie || t1d > p_);
    std::uint8_t list = from_t1 ? kT1 : kT2;
    std::uint32_t v = lru_candidate(list, pinned, inc);
    if (v == kNil) {
      list = from_t1 ? kT2 : kT1;
      v = lru_candidate(list, pinned, inc);
    }
    if (v == kNil) return kNoKey;
    const std::uint64_t key = nodes_[v].key;
    const std::uint64_t size = nodes_[v].size;
    nodes_.unlink(v);
    const std::uint8_t ghost = list == kT1 ? kB1 : kB2;
    if (size > c_) {
      release(v);
      return key;
    }
    // Ghosts stay within c (never with unit sizes: there the paper's bounds imply it).
    while (nodes_.weight(kB1) + nodes_.weight(kB2) + size > c_) drop_lru(nodes_.count(kB2) > 0 ? kB2 : kB1);
    nodes_.push_front(v, ghost, size);
    return key;
  }
  void restore(std::uint64_t key, std::uint64_t size) override {
    std::uint32_t n;
    std::uint8_t list = kT1;
    if (const std::uint32_t* g = index_.find(key)) {
      n = *g;
      if (nodes_[n].list == kT1 || nodes_[n].list == kT2) return;
      list = nodes_[n].list == kB1 ? kT1 : kT2;
      nodes_.unlink(n);
    } else {
      n = alloc(key);
    }
    nodes_.push_back(n, list, size);
  }
  void set_capacity(std::uint64_t capacity) override {
    c_ = capacity;
    p_ = std::min(p_, static_cast<double>(c_));
    while (nodes_.weight(kT1) + nodes_.weight(kB1) > c_ && nodes_.count(kB1) > 0) drop_lru(kB1);
    while (nodes_.weight(kT1) + nodes_.weight(kT2) + nodes_.weight(kB1) + nodes_.weight(kB2) > 2 * c_ && nodes_.count(kB2) > 0)
      drop_lru(kB2);
    while (nodes_.weight(kB1) + nodes_.weight(kB2) > c_) drop_lru(nodes_.count(kB2) > 0 ? kB2 : kB1);
    incoming_ = kNil;
  }
  std::uint64_t size() const override { return nodes_.count(kT1) + nodes_.count(kT2); }

 private:
  static constexpr std::uint32_t kNil = ~std::uint32_t{0};
  static constexpr std::uint8_t kT1 = 0, kT2 = 1, kB1 = 2, kB2 = 3;  // also the sentinels' nodes
  struct Node {
    std::uint64_t key = kNoKey;
    std::uint64_t size = 0;
    std::uint32_t prev = 0, next = 0;  // towards the MRU / the LRU end
    std::uint8_t list = 0;
  };

  // The least recently used key of `list` that is neither pinned nor `skip`; kNil if none.
  std::uint32_t lru_candidate(std::uint8_t list, Pinned pinned, std::uint32_t skip) const {
    for (std::uint32_t n = nodes_.back(list); n != list; n = nodes_[n].prev)
      if (n != skip && !pinned(nodes_[n].key)) return n;
    return kNil;
  }
  void drop_lru(std::uint8_t list) {
    const std::uint32_t n = nodes_.back(list);
    nodes_.unlink(n);
    release(n);
  }

  std::uint32_t alloc(std::uint64_t key) {
    const std::uint32_t n = nodes_.alloc(key);
    index_.put(key, n);
    return n;
  }
  // Forgets the node's key entirely (no ghost).
  void release(std::uint32_t n) {
    if (n == incoming_) incoming_ = kNil;
    index_.erase(nodes_[n].key);
    nodes_.release(n);
  }

  // Nodes 0-3: the sentinels of T1, T2, B1, B2 (next: MRU end; prev: LRU end).
  WeightedLists<Node, 4> nodes_;  // node_lists.h: each list's weight (in the owner's unit) and key count
  PageMap<std::uint32_t> index_;  // cached and ghost keys
  std::uint64_t c_;                        // capacity, in the owner's unit
  double p_ = 0;                           // target weight of T1, in [0, c]
  std::uint32_t incoming_ = kNil;          // the node admitted last (see evict)
  bool from_b2_ = false;                   // it was a B2 ghost (REPLACE's tie-break)
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_arc(std::uint64_t capacity) {
  return std::make_unique<PolicyArc>(capacity);
}

}  // namespace vtsim
