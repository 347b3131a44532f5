// Level-weighted LRU for mip pyramids: evict the key whose last request, pushed later by
// kFramesPerLevel frames per mip level, is oldest. What a texture streamer knows and a generic
// cache does not: a page at level l covers 4^l the area of a level-0 page and is the fallback of
// every finer page under it (Yao 2011 §3.1, the fallback chain), so of two pages that left the
// view at the same time the coarser one is likelier to be wanted again (any part of its larger
// area coming back into view wants it), and losing it blurs more of the screen. Pages in use this
// frame are never victims (the pool's Pinned); ties go to the finer page.
//
// One LRU list per level (the level of the key's TileKey; keys whose level bits exceed the table
// share the last list), each ordered by last request, so the oldest key of a level is its tail:
// evict compares the first unpinned key from each level's tail. Ages are frames (begin_frame);
// an owner that never calls begin_frame (frame 0 throughout) gets pure level order, finest first,
// LRU within a level.
//
// Complexity: admit, hit, remove O(1) expected; evict O(levels + pinned keys passed). Memory: 32
// bytes per node + 2-4 PageMap slots of 16 bytes per key.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "cache/policy/node_lists.h"
#include "core/tile_key.h"

namespace vtsim {
namespace {

// 120 frames (2 s at 60 Hz) per level: a page one level coarser outlives a finer one that left
// the view up to 2 s later, about the time a turning camera takes to bring back what it turned
// from. Measured against 8 and 30 frames (docs/vt.md, "Policies in the live caches"): 8 lost the
// turn's gain at a 128-page pool (3.3% blurry against 2.3%), 30 kept it with 0-20 more pool
// misses than 120 on the town walk and the turn.
constexpr std::int64_t kLevelLruFramesPerLevel = 120;
constexpr std::size_t kLevelLruLists = 32;

class PolicyLevelLru final : public IReplacementPolicy {
 public:
  void admit(std::uint64_t key, std::uint64_t) override {
    if (index_.contains(key)) return hit(key);  // a contract breach by the owner: keep the lists whole
    const std::uint32_t n = nodes_.alloc(key);
    nodes_[n].last = frame_;
    nodes_[n].list = list_of(key);
    index_.put(key, n);
    nodes_.insert_after(nodes_[n].list, n);
  }
  void hit(std::uint64_t key) override {
    if (const std::uint32_t* n = index_.find(key)) {
      nodes_.unlink(*n);
      nodes_[*n].last = frame_;
      nodes_.insert_after(nodes_[*n].list, *n);
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
    std::uint32_t best = 0;
    std::int64_t best_score = 0;
    for (std::size_t l = 0; l < kLevelLruLists; ++l) {
      for (std::uint32_t n = nodes_[sentinel(l)].prev; n != sentinel(l); n = nodes_[n].prev) {
        if (pinned(nodes_[n].key)) continue;
        const std::int64_t score = nodes_[n].last + kLevelLruFramesPerLevel * static_cast<std::int64_t>(l);
        if (best == 0 || score < best_score) best = n, best_score = score;
        break;
      }
    }
    if (best == 0) return kNoKey;
    const std::uint64_t key = nodes_[best].key;
    nodes_.unlink(best);
    nodes_.release(best);
    index_.erase(key);
    return key;
  }
  void set_capacity(std::uint64_t) override {}
  void begin_frame(int frame) override { frame_ = frame; }
  std::uint64_t size() const override { return index_.size(); }

 private:
  struct Node {
    std::uint64_t key = kNoKey;
    std::int64_t last = 0;  // frame of the last request
    std::uint32_t prev = 0, next = 0;
    std::uint32_t list = 0;  // its level's sentinel
  };
  // Nodes 0..kLevelLruLists-1 are the lists' sentinels (next: most recent, prev: least); node 0
  // doubles as "none" in evict, as a sentinel is never a candidate.
  static std::uint32_t sentinel(std::size_t level) { return static_cast<std::uint32_t>(level); }
  static std::uint32_t list_of(std::uint64_t key) {
    TileKey k;
    k.bits = key;
    const auto l = static_cast<std::size_t>(k.level());
    return sentinel(l < kLevelLruLists ? l : kLevelLruLists - 1);
  }
  static NodeSlab<Node> make_sentinels() {
    NodeSlab<Node> s(kLevelLruLists);
    for (std::uint32_t i = 0; i < kLevelLruLists; ++i) s[i].list = i;
    return s;
  }

  NodeSlab<Node> nodes_ = make_sentinels();
  PageMap<std::uint32_t> index_;
  std::int64_t frame_ = 0;
};

}  // namespace

std::unique_ptr<IReplacementPolicy> make_policy_level_lru(std::uint64_t) { return std::make_unique<PolicyLevelLru>(); }

}  // namespace vtsim
