#pragma once
// The RAM tier of disk -> RAM -> VRAM (Yao 2007 §4-2, two-level cache): decoded tiles keyed by
// TileKey and weighted by bytes, evicted least-recently-used first under a hard byte cap (Unity Clipmap's
// Unity package capped entries softly and overshot 20x; this one never exceeds its capacity).
// The contract is modelled on folly's EvictingCacheMap; docs/cache.md has the design and figures.
#include <algorithm>
#include <concepts>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/tile_key.h"

namespace vtsim {

// Why an entry left an LruCache; every removal names exactly one.
enum class LruRemoval : std::uint8_t {
  kEvicted,   // insert() made room for a new entry (least-recently-used first)
  kShrunk,    // set_capacity() lowered the capacity below the bytes held
  kReplaced,  // insert() under a key already present: the old value leaves
  kCleared,   // clear()
  kErased,    // erase() by the owner
};

constexpr const char* lru_removal_name(LruRemoval r) {
  switch (r) {
    case LruRemoval::kEvicted: return "evicted";
    case LruRemoval::kShrunk: return "shrunk";
    case LruRemoval::kReplaced: return "replaced";
    case LruRemoval::kCleared: return "cleared";
    case LruRemoval::kErased: return "erased";
  }
  return "?";
}

struct LruStats {
  std::uint64_t hits = 0;           // get() calls that found their key (peek/contains not counted)
  std::uint64_t misses = 0;         // get() calls that did not
  std::uint64_t inserts = 0;        // insert() calls that stored their entry (new or replacing)
  std::uint64_t replacements = 0;   // of those, how many replaced an entry under the same key
  std::uint64_t rejected = 0;       // insert() calls refused: entry larger than the capacity
  std::uint64_t evictions = 0;      // entries removed for room or by set_capacity (kEvicted+kShrunk)
  std::uint64_t evicted_bytes = 0;  // bytes of those entries
};

// Sets a cache's "inside the removal hook" flag for its lifetime: LruCache and PolicyCache refuse
// re-entrant mutations while it is set.
class RemovalHookScope {
 public:
  explicit RemovalHookScope(bool& flag) : flag_(flag) { flag_ = true; }
  ~RemovalHookScope() { flag_ = false; }
  RemovalHookScope(const RemovalHookScope&) = delete;
  RemovalHookScope& operator=(const RemovalHookScope&) = delete;

 private:
  bool& flag_;
};

enum class LruInsert : std::uint8_t {
  kInserted,  // a new key is now the most-recent entry
  kReplaced,  // the key was present; its old value went through the hook, the new one is most-recent
  kRejected,  // bytes > capacity(): nothing changed (an old entry under the key, if any, stays)
};

// Byte-weighted LRU map TileKey -> Value with a hard capacity.
//
// Complexity: get, peek, contains, erase: expected O(1). insert: expected O(1) plus O(1) per entry
// it evicts, amortised over table growth, which happens only while the entry count reaches a new
// high: no allocation in steady state. clear: O(size). set_capacity: O(evicted). Iteration:
// O(size). Memory: 1 + sizeof(Node) bytes per table slot (a control byte; Node = key, bytes, two
// 32-bit links, Value: 32 bytes for an 8-byte Value); the table is a power of two kept between 1/8
// and 1/4 full, so 4-8 slots (132-264 bytes with an 8-byte Value) per entry: 0.3-0.7% of a 38 KB
// decoded tile. Keep Value small (a handle).
//
// Layout: open addressing with linear probing over a power-of-two table (deletion by backward
// shift, so there are no tombstones and probe lengths never degrade) whose slots are the nodes
// themselves: the slab of nodes is indexed like the table (slot i holds node i + 1; node 0 is the
// sentinel of the intrusive doubly linked recency list, linked by 32-bit node indices), beside a
// 1-byte control array (empty, or 7 hash bits). A lookup computes the addresses of its control
// byte and node from the hash alone and finds key, links and value in one node line; a miss
// mostly reads control bytes only. A std::unordered_map + std::list LRU makes four dependent loads
// (bucket, node before, node, list node) before it can relink. A backward shift moves a node and
// repoints its two list neighbours. docs/cache.md gives the measurements behind each choice.
//
// Thread-safety: none. One owner (the frame loop) calls it; const members are safe to call
// concurrently only while nobody mutates.
//
// The removal hook: every entry that leaves the cache while it is alive leaves through the hook,
// called once per entry as hook(key, value&, bytes, reason) — capacity evictions, set_capacity,
// replacement on insert, clear, and also erase(). That includes erase so that the owner releases
// resources and accounts bytes in exactly one place (the VT page pool frees a VRAM slot there,
// however the page left). When the hook runs the entry is already gone: size() and bytes() exclude
// it and contains(key) is false; value& refers to the value moved out of the cache, valid until
// the hook returns and then destroyed (move from it in the hook to keep it). During the evictions
// an insert() makes, the entry being inserted is already in place (peek() sees it, size() counts
// it) while bytes() does not count it yet. The hook may call peek(), contains() and the other
// const members; calling get (it reorders the list), insert, erase, clear, set_capacity, reserve
// or set_hook from it throws std::logic_error. If the hook throws, the entry stays removed, the
// exception propagates and the operation that triggered it stops there with the cache consistent
// and within capacity (an insert whose eviction hook throws does not insert its entry). The
// destructor and move-assignment discard entries without calling the hook: call clear() first if
// their resources must be released through it. A moved-from cache may only be assigned to or
// destroyed.
//
// Invalidation: a pointer returned by get()/peek() stays valid across get, peek, contains and the
// observers, and is invalidated by insert, erase, clear, set_capacity and reserve (entries move
// within the table when others leave and when it grows).
template <class Value>
  requires std::default_initializable<Value> && std::is_nothrow_move_constructible_v<Value> &&
           std::is_nothrow_move_assignable_v<Value>
class LruCache {
 public:
  using Hook = std::function<void(TileKey key, Value& value, std::uint64_t bytes, LruRemoval reason)>;

  explicit LruCache(std::uint64_t capacity_bytes, Hook hook = {})
      : capacity_(capacity_bytes), hook_(std::move(hook)), ctrl_(kMinSlots, kEmpty), nodes_(kMinSlots + 1) {
    mask_ = kMinSlots - 1;
    shift_ = 64 - 4;  // log2(kMinSlots) = 4
  }
  LruCache(const LruCache&) = delete;
  LruCache& operator=(const LruCache&) = delete;
  LruCache(LruCache&&) noexcept = default;
  LruCache& operator=(LruCache&&) noexcept = default;
  ~LruCache() = default;

  void set_hook(Hook hook) {
    check_not_in_hook("set_hook");
    hook_ = std::move(hook);
  }

  // Promoting lookup: the entry becomes most-recent. Counts a hit or a miss.
  Value* get(TileKey key) {
    check_not_in_hook("get");
    // probe() written out: the hot path of the frame loop, and returning from inside the loop
    // saves the Probe round trip.
    const std::uint64_t product = key.bits * kFib;
    const std::uint8_t c = ctrl_of(product);
    for (std::size_t i = static_cast<std::size_t>(product >> shift_);; i = (i + 1) & mask_) {
      const std::uint8_t ci = ctrl_[i];
      if (ci == kEmpty) {
        ++stats_.misses;
        return nullptr;
      }
      if (ci == c && nodes_[i + 1].key == key) {
        ++stats_.hits;
        const auto n = static_cast<std::uint32_t>(i) + 1;
        move_to_front(n);
        return &nodes_[n].value;
      }
    }
  }

  // Non-promoting lookups: order and counters unchanged.
  const Value* peek(TileKey key) const {
    const std::uint32_t n = find(key);
    return n == kNone ? nullptr : &nodes_[n].value;
  }
  Value* peek(TileKey key) {
    const std::uint32_t n = find(key);
    return n == kNone ? nullptr : &nodes_[n].value;
  }
  bool contains(TileKey key) const { return find(key) != kNone; }
  // Bytes charged for key, or 0 when absent (an entry may also weigh 0 bytes: use contains()).
  std::uint64_t bytes_of(TileKey key) const {
    const std::uint32_t n = find(key);
    return n == kNone ? 0 : nodes_[n].bytes;
  }

  // Stores (key, value) weighing `bytes` as the most-recent entry. Evicts least-recently-used
  // entries (reason kEvicted) until it fits; a present key's old value leaves first (kReplaced).
  // Rejects, changing nothing, an entry larger than the capacity. bytes() never exceeds
  // capacity(), at any point of the call. If growing the table for a new high of entries throws
  // (std::bad_alloc; std::length_error past 2^29 entries) nothing has changed.
  LruInsert insert(TileKey key, Value value, std::uint64_t bytes) {
    check_not_in_hook("insert");
    if (bytes > capacity_) {
      ++stats_.rejected;
      return LruInsert::kRejected;
    }
    Probe p = probe(key);
    const bool replaced = p.found;
    if (replaced) remove_slot(p.slot, LruRemoval::kReplaced);
    bool moved = replaced;
    // Grow before evicting, so a failed allocation leaves the cache as it was (a replacement
    // freed a slot, so it never grows).
    if ((size_ + 1) * kMaxLoadDen > slots() * kMaxLoadNum) {
      if (slots() > kMaxSlots / 2) throw std::length_error("LruCache: more than 2^29 entries");
      rehash(slots() * 2);
      moved = true;
    }
    // A removal's backward shift or a rehash may have shortened the probe sequence: probe again.
    if (moved) p = probe(key);
    // Place the entry at the front first: the evictions' backward shifts then keep it reachable
    // (moving it if need be, links and all) and no second probe is needed. Its bytes are charged
    // after the evictions, so they never pick it: it is the tail only when it is alone, and then
    // bytes() is 0 and the loop has stopped (hooks cannot reorder the list: get() is refused).
    ctrl_[p.slot] = p.ctrl;
    const std::uint32_t n = static_cast<std::uint32_t>(p.slot) + 1;
    Node& node = nodes_[n];
    node.key = key;
    node.bytes = bytes;
    node.value = std::move(value);
    link_front(n);
    ++size_;
    try {
      while (bytes > capacity_ - bytes_) remove_slot(nodes_[0].prev - 1, LruRemoval::kEvicted);
    } catch (...) {
      // A hook threw: the entry is not inserted after all. It leaves without a hook call, as it
      // was never charged; the value passed in is destroyed.
      const Probe q = probe(key);
      unlink(static_cast<std::uint32_t>(q.slot) + 1);
      erase_slot(q.slot);
      --size_;
      throw;
    }
    bytes_ += bytes;
    ++stats_.inserts;
    if (replaced) ++stats_.replacements;
    return replaced ? LruInsert::kReplaced : LruInsert::kInserted;
  }

  // Removes key through the hook (reason kErased). Returns whether it was present.
  bool erase(TileKey key) {
    check_not_in_hook("erase");
    const Probe p = probe(key);
    if (!p.found) return false;
    remove_slot(p.slot, LruRemoval::kErased);
    return true;
  }

  // Removes every entry through the hook (reason kCleared), least-recent first. Keeps the
  // allocated table (clear and refill allocates nothing) and the counters.
  void clear() {
    check_not_in_hook("clear");
    while (size_ > 0) remove_slot(nodes_[0].prev - 1, LruRemoval::kCleared);
  }

  // Sets the capacity; first evicts least-recent entries (reason kShrunk) until bytes() fits it.
  // capacity() changes once they are gone, so even hooks never see bytes() > capacity(); if a hook
  // throws, capacity() keeps its old value.
  void set_capacity(std::uint64_t capacity_bytes) {
    check_not_in_hook("set_capacity");
    while (bytes_ > capacity_bytes) remove_slot(nodes_[0].prev - 1, LruRemoval::kShrunk);
    capacity_ = capacity_bytes;
  }

  // Pre-sizes the table for `entries` simultaneous entries: no allocation until the entry count
  // exceeds it.
  void reserve(std::size_t entries) {
    check_not_in_hook("reserve");
    if (entries > kMaxSlots / 4) throw std::length_error("LruCache::reserve: more than 2^29 entries");
    std::size_t want = slots();
    while (entries * kMaxLoadDen > want * kMaxLoadNum) want *= 2;
    if (want != slots()) rehash(want);
  }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  std::uint64_t bytes() const { return bytes_; }
  std::uint64_t capacity() const { return capacity_; }
  const LruStats& stats() const { return stats_; }
  void reset_stats() { stats_ = {}; }

  // Diagnostics (O(table)): how far entries sit from their home slot; a lookup reads
  // displacement + 1 control bytes.
  struct ProbeStats {
    double mean_displacement = 0;  // slots, over entries
    std::size_t max_displacement = 0;
    std::size_t slots = 0;  // table size
  };
  ProbeStats probe_stats() const {
    ProbeStats ps;
    ps.slots = slots();
    std::uint64_t sum = 0;
    for (std::size_t i = 0; i < slots(); ++i) {
      if (ctrl_[i] == kEmpty) continue;
      const std::size_t d = (i - home(nodes_[i + 1].key)) & mask_;
      sum += d;
      ps.max_displacement = std::max(ps.max_displacement, d);
    }
    if (size_) ps.mean_displacement = static_cast<double>(sum) / static_cast<double>(size_);
    return ps;
  }

  // Least- and most-recently-used keys (nullopt when empty); neither promotes.
  std::optional<TileKey> lru_key() const {
    return size_ ? std::optional<TileKey>(nodes_[nodes_[0].prev].key) : std::nullopt;
  }
  std::optional<TileKey> mru_key() const {
    return size_ ? std::optional<TileKey>(nodes_[nodes_[0].next].key) : std::nullopt;
  }

  // Calls f(key, const Value&, bytes) for every entry from least- to most-recently used.
  // f must not mutate the cache.
  template <class F>
  void for_each_lru_to_mru(F&& f) const {
    for (std::uint32_t n = nodes_[0].prev; n != 0; n = nodes_[n].prev)
      f(nodes_[n].key, nodes_[n].value, nodes_[n].bytes);
  }

 private:
  static constexpr std::uint8_t kEmpty = 0;  // control byte of an empty slot
  static constexpr std::uint32_t kNone = 0;  // find(): absent (node 0 is the sentinel)
  static constexpr std::size_t kMinSlots = 16;
  // Node indices (slot + 1) are 32-bit: at most 2^31 slots (2^29 entries at the maximum load).
  static constexpr std::size_t kMaxSlots = std::size_t{1} << 31;
  // At most 1/4 full: the first probe ends a miss ~80% of the time (Knuth, TAOCP vol. 3 §6.4:
  // expected probes 1.17 hit / 1.39 miss at load 1/4, against 1.5 / 2.5 at 1/2), so the probe
  // and backward-shift loops rarely mispredict; measured 1.5-2x faster inserts than at 1/2
  // (docs/cache.md), for 4-8 nodes per entry instead of 2-4.
  static constexpr std::size_t kMaxLoadNum = 1, kMaxLoadDen = 4;

  struct Node {
    TileKey key;
    std::uint64_t bytes = 0;
    std::uint32_t prev = 0;  // towards the most-recent end (0: this is the most recent)
    std::uint32_t next = 0;  // towards the least-recent end (0: this is the least recent)
    Value value{};
  };
  struct Probe {
    std::size_t slot;  // the key's slot, or the empty slot ending its probe sequence
    bool found;
    std::uint8_t ctrl;  // the key's control byte
  };

  void check_not_in_hook(const char* what) const {
    if (in_hook_) throw std::logic_error(std::string("LruCache::") + what + " called from the removal hook");
  }

  // Fibonacci hashing (Knuth, TAOCP vol. 3 §6.4, multiplicative hashing by 2^64/phi): the home
  // slot is the top log2(slots) bits of key * 0x9E37...15. One multiply instead of mix64's two
  // plus shifts, on the critical path of every lookup; and the keys of a tile window (arithmetic
  // progressions in x and y) land spread by the three-distance theorem: mean displacement
  // 0-0.01 slots on window and grid key sets against 0.07-0.17 for mix64 (docs/cache.md; tested
  // in tests/test_lru_cache.cpp).
  static constexpr std::uint64_t kFib = 0x9E3779B97F4A7C15ULL;  // 2^64 / golden ratio, odd
  std::size_t home(TileKey key) const { return static_cast<std::size_t>((key.bits * kFib) >> shift_); }
  // Control byte: 0x80 | product bits 32-38, below the home bits of any table up to 2^25 slots
  // (larger ones share bits with the home: a weaker filter, never a wrong answer). An empty slot
  // or a mismatch settles a probe step without reading the node (a miss usually reads no node at
  // all); a false match (about 1 in 128 occupied slots) costs one key comparison.
  static std::uint8_t ctrl_of(std::uint64_t product) {
    return static_cast<std::uint8_t>(0x80u | ((product >> 32) & 0x7Fu));
  }
  std::size_t slots() const { return mask_ + 1; }

  // The slot holding key, or the empty slot that ends its probe sequence. Reads the 1-byte
  // control array, and a node only when its control byte matches: a hit in its home slot costs
  // one control byte and one node line.
  Probe probe(TileKey key) const {
    const std::uint64_t product = key.bits * kFib;
    const std::uint8_t c = ctrl_of(product);
    for (std::size_t i = static_cast<std::size_t>(product >> shift_);; i = (i + 1) & mask_) {
      const std::uint8_t ci = ctrl_[i];
      if (ci == kEmpty) return {i, false, c};
      if (ci == c && nodes_[i + 1].key == key) return {i, true, c};
    }
  }
  // Node index holding key, or kNone.
  std::uint32_t find(TileKey key) const {
    const Probe p = probe(key);
    return p.found ? static_cast<std::uint32_t>(p.slot) + 1 : kNone;
  }

  // Unlinks the entry in `slot`, closes the hole by backward shift, then hands the value to the
  // hook. Counters and sizes are settled before the hook runs.
  void remove_slot(std::size_t slot, LruRemoval reason) {
    Node& node = nodes_[slot + 1];
    const TileKey key = node.key;
    const std::uint64_t b = node.bytes;
    Value value = std::move(node.value);
    unlink(static_cast<std::uint32_t>(slot) + 1);
    if (reason != LruRemoval::kErased && reason != LruRemoval::kReplaced) {
      // Tail removals come in runs: fetch the new tail's list neighbour, which the next one
      // unlinks, while this one finishes. A hint only; nothing depends on it.
      __builtin_prefetch(&nodes_[nodes_[nodes_[0].prev].prev]);
    }
    erase_slot(slot);
    --size_;
    bytes_ -= b;
    if (reason == LruRemoval::kEvicted || reason == LruRemoval::kShrunk) {
      ++stats_.evictions;
      stats_.evicted_bytes += b;
    }
    if (hook_) {
      RemovalHookScope scope(in_hook_);
      hook_(key, value, b, reason);
    }
  }

  // Backward-shift deletion: pull later members of the cluster into the hole when their home
  // does not lie cyclically in (hole, j], so every key stays reachable from its home slot. A
  // moved node keeps its place in the recency list: its neighbours are repointed.
  void erase_slot(std::size_t hole) {
    std::size_t j = hole;
    for (;;) {
      j = (j + 1) & mask_;
      const std::uint8_t c = ctrl_[j];
      if (c == kEmpty) break;
      if (((j - home(nodes_[j + 1].key)) & mask_) >= ((j - hole) & mask_)) {
        ctrl_[hole] = c;
        const auto to = static_cast<std::uint32_t>(hole) + 1;
        Node& dst = nodes_[to];
        dst = std::move(nodes_[j + 1]);
        nodes_[dst.prev].next = to;
        nodes_[dst.next].prev = to;
        hole = j;
      }
    }
    ctrl_[hole] = kEmpty;
    nodes_[hole + 1].value = Value{};  // a moved-from value may still hold resources
  }

  // Moves every entry into a table of new_slots slots, keeping the recency order.
  void rehash(std::size_t new_slots) {
    std::vector<std::uint8_t> ctrl(new_slots, kEmpty);
    std::vector<Node> nodes(new_slots + 1);
    std::vector<std::uint32_t> where(nodes_.size(), 0);  // old node index -> new (sentinel 0 -> 0)
    const std::size_t m = new_slots - 1;
    int shift = 64;
    for (std::size_t n = new_slots; n > 1; n >>= 1) --shift;
    // Place everything before moving anything: only the allocations above throw.
    for (std::size_t s = 0; s < slots(); ++s) {
      if (ctrl_[s] == kEmpty) continue;
      const std::uint64_t product = nodes_[s + 1].key.bits * kFib;
      std::size_t i = static_cast<std::size_t>(product >> shift);
      while (ctrl[i] != kEmpty) i = (i + 1) & m;
      ctrl[i] = ctrl_[s];
      where[s + 1] = static_cast<std::uint32_t>(i) + 1;
    }
    nodes[0].prev = where[nodes_[0].prev];
    nodes[0].next = where[nodes_[0].next];
    for (std::size_t s = 0; s < slots(); ++s) {
      if (ctrl_[s] == kEmpty) continue;
      Node& dst = nodes[where[s + 1]];
      dst = std::move(nodes_[s + 1]);
      dst.prev = where[dst.prev];
      dst.next = where[dst.next];
    }
    ctrl_.swap(ctrl);
    nodes_.swap(nodes);
    mask_ = m;
    shift_ = shift;
  }

  void unlink(std::uint32_t n) {
    Node& node = nodes_[n];
    nodes_[node.prev].next = node.next;
    nodes_[node.next].prev = node.prev;
  }
  void link_front(std::uint32_t n) {
    Node& node = nodes_[n];
    node.prev = 0;
    node.next = nodes_[0].next;
    nodes_[node.next].prev = n;
    nodes_[0].next = n;
  }
  void move_to_front(std::uint32_t n) {
    if (nodes_[0].next == n) return;
    unlink(n);
    link_front(n);
  }

  std::uint64_t capacity_ = 0;
  std::uint64_t bytes_ = 0;
  std::size_t size_ = 0;
  Hook hook_;
  std::vector<std::uint8_t> ctrl_;  // per slot: kEmpty, or 0x80 | 7 hash bits of its key
  std::vector<Node> nodes_;         // [0] list sentinel (next: most recent, prev: least recent);
                                    // [i + 1] the entry in slot i
  std::size_t mask_ = 0;
  int shift_ = 0;
  LruStats stats_;
  bool in_hook_ = false;
};

}  // namespace vtsim
