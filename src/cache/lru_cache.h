#pragma once
// The RAM tier of disk -> RAM -> VRAM (seed 000 §4-2, two-level cache): decoded tiles keyed by
// TileKey and weighted by bytes, evicted least-recently-used first under a hard byte cap (seed 003's
// Unity package capped entries softly and overshot 20x; this one never exceeds its capacity).
// The contract is modelled on folly's EvictingCacheMap; docs/cache.md has the figures.
#include <concepts>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
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

enum class LruInsert : std::uint8_t {
  kInserted,  // a new key is now the most-recent entry
  kReplaced,  // the key was present; its old value went through the hook, the new one is most-recent
  kRejected,  // bytes > capacity(): nothing changed (an old entry under the key, if any, stays)
};

// Byte-weighted LRU map TileKey -> Value with a hard capacity.
//
// Complexity: get, peek, contains, erase: expected O(1). insert: expected O(1) plus O(1) per entry
// it evicts; amortised O(1) allocation only while the entry count reaches a new high (slab and
// table growth); none in steady state. clear: O(size). set_capacity: O(evicted). Iteration: O(size).
// Memory: 16 bytes per hash slot (table kept at most half full, power of two) plus one node
// (key, bytes, two 32-bit links, Value) per entry ever simultaneously resident.
//
// Layout: an open-addressing table with linear probing over a power-of-two array, hashed by mix64,
// deletions by backward shift (no tombstones, so probe lengths never degrade); nodes live in a slab
// indexed by 32-bit ints and are threaded by an intrusive doubly linked list (node 0 is the list
// sentinel); freed nodes are recycled through a free list.
//
// Thread-safety: none. One owner (the frame loop) calls it; const members are safe to call
// concurrently only while nobody mutates.
//
// The removal hook: every entry that leaves the cache while it is alive leaves through the hook,
// called once per entry as hook(key, value&, bytes, reason) — capacity evictions, set_capacity,
// replacement on insert, clear, and also erase(). That includes erase so that the owner releases
// resources and accounts bytes in exactly one place (the VT page pool frees a VRAM slot there,
// however the page left). When the hook runs the entry is already gone: size() and bytes() exclude
// it, contains(key) is false; value& stays valid until the hook returns and is then reset to
// Value{} (a held buffer is released; move it out in the hook to keep it). The hook may call get(),
// peek(), contains() and the observers; calling insert, erase, clear, set_capacity or reserve from
// it throws std::logic_error. If the hook throws, the entry stays removed, the exception propagates
// and the operation that triggered it stops there with the cache consistent and within capacity.
// The destructor and move-assignment discard entries without calling the hook: call clear() first
// if their resources must be released through it. A moved-from cache may only be assigned to or
// destroyed.
//
// Invalidation: a pointer returned by get()/peek() stays valid across get, peek, contains and the
// observers, and is invalidated by insert (it may evict that entry, replace it or grow the slab),
// erase, clear, set_capacity and reserve.
template <class Value>
  requires std::default_initializable<Value> && std::movable<Value>
class LruCache {
 public:
  using Hook = std::function<void(TileKey key, Value& value, std::uint64_t bytes, LruRemoval reason)>;

  explicit LruCache(std::uint64_t capacity_bytes, Hook hook = {})
      : capacity_(capacity_bytes), hook_(std::move(hook)), nodes_(1), slots_(kMinSlots) {
    mask_ = slots_.size() - 1;
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
    const std::uint32_t n = slots_[find_slot(key, tag_of(key))].node;
    if (n == kNil) {
      ++stats_.misses;
      return nullptr;
    }
    ++stats_.hits;
    move_to_front(n);
    return &nodes_[n].value;
  }

  // Non-promoting lookups: order and counters unchanged.
  const Value* peek(TileKey key) const {
    const std::uint32_t n = slots_[find_slot(key, tag_of(key))].node;
    return n == kNil ? nullptr : &nodes_[n].value;
  }
  Value* peek(TileKey key) {
    const std::uint32_t n = slots_[find_slot(key, tag_of(key))].node;
    return n == kNil ? nullptr : &nodes_[n].value;
  }
  bool contains(TileKey key) const { return slots_[find_slot(key, tag_of(key))].node != kNil; }
  // Bytes charged for key, or 0 when absent (an entry may also weigh 0 bytes: use contains()).
  std::uint64_t bytes_of(TileKey key) const {
    const std::uint32_t n = slots_[find_slot(key, tag_of(key))].node;
    return n == kNil ? 0 : nodes_[n].bytes;
  }

  // Stores (key, value) weighing `bytes` as the most-recent entry. Evicts least-recently-used
  // entries (reason kEvicted) until it fits; a present key's old value leaves first (kReplaced).
  // Rejects, changing nothing, an entry larger than the capacity. bytes() never exceeds
  // capacity(), at any point of the call. If allocating room for a new high of entries throws
  // (std::bad_alloc, std::length_error past 2^31-1 entries) nothing has changed.
  LruInsert insert(TileKey key, Value value, std::uint64_t bytes) {
    check_not_in_hook("insert");
    if (bytes > capacity_) {
      ++stats_.rejected;
      return LruInsert::kRejected;
    }
    const std::uint32_t tag = tag_of(key);
    std::size_t slot = find_slot(key, tag);
    bool replaced = false;
    if (const std::uint32_t old = slots_[slot].node; old != kNil) {
      remove_node(old, LruRemoval::kReplaced);
      replaced = true;
    }
    // Allocate before evicting, so a failed allocation leaves the cache as it was.
    bool moved = replaced;
    if ((size_ + 1) * kMaxLoadDen > slots_.size() * kMaxLoadNum) {
      rehash(slots_.size() * 2);
      moved = true;
    }
    if (free_ == kNil) grow_slab();
    while (bytes > capacity_ - bytes_) {
      remove_node(nodes_[0].prev, LruRemoval::kEvicted);
      moved = true;
    }

    const std::uint32_t n = free_;
    Node& node = nodes_[n];
    free_ = node.next;
    node.key = key;
    node.bytes = bytes;
    node.value = std::move(value);
    link_front(n);
    // A removal's backward shift or a rehash may have shortened the probe sequence: probe again.
    if (moved) slot = find_slot(key, tag);
    slots_[slot] = Slot{tag, n};
    ++size_;
    bytes_ += bytes;
    ++stats_.inserts;
    if (replaced) ++stats_.replacements;
    return replaced ? LruInsert::kReplaced : LruInsert::kInserted;
  }

  // Removes key through the hook (reason kErased). Returns whether it was present.
  bool erase(TileKey key) {
    check_not_in_hook("erase");
    const std::uint32_t n = slots_[find_slot(key, tag_of(key))].node;
    if (n == kNil) return false;
    remove_node(n, LruRemoval::kErased);
    return true;
  }

  // Removes every entry through the hook (reason kCleared), least-recent first. Keeps the
  // allocated slab and table (clear and refill allocates nothing) and the counters.
  void clear() {
    check_not_in_hook("clear");
    while (size_ > 0) remove_node(nodes_[0].prev, LruRemoval::kCleared);
  }

  // Sets the capacity; first evicts least-recent entries (reason kShrunk) until bytes() fits it.
  // capacity() changes once they are gone, so even hooks never see bytes() > capacity(); if a hook
  // throws, capacity() keeps its old value.
  void set_capacity(std::uint64_t capacity_bytes) {
    check_not_in_hook("set_capacity");
    while (bytes_ > capacity_bytes) remove_node(nodes_[0].prev, LruRemoval::kShrunk);
    capacity_ = capacity_bytes;
  }

  // Pre-allocates room for `entries` simultaneous entries (slab and table): no allocation until
  // the entry count exceeds it.
  void reserve(std::size_t entries) {
    check_not_in_hook("reserve");
    if (entries > kMaxEntries) throw std::length_error("LruCache::reserve: more than 2^31-1 entries");
    std::size_t want = slots_.size();
    while (entries * kMaxLoadDen > want * kMaxLoadNum) want *= 2;
    if (want != slots_.size()) rehash(want);
    while (nodes_.size() - 1 < entries) grow_slab();
  }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  std::uint64_t bytes() const { return bytes_; }
  std::uint64_t capacity() const { return capacity_; }
  const LruStats& stats() const { return stats_; }
  void reset_stats() { stats_ = {}; }

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
  static constexpr std::uint32_t kNil = std::numeric_limits<std::uint32_t>::max();
  // Homes are taken from a 32-bit tag, so the table stays within 2^32 slots, half full at most.
  static constexpr std::size_t kMaxEntries = (std::size_t{1} << 31) - 1;
  static constexpr std::size_t kMinSlots = 16;
  // Linear probing stays short up to half full: expected probes 1.5 (hit) and 2.5 (miss) at load
  // 1/2 (Knuth, TAOCP vol. 3 §6.4), against 2.5 and 8.5 at 3/4.
  static constexpr std::size_t kMaxLoadNum = 1, kMaxLoadDen = 2;

  struct Node {
    TileKey key;
    std::uint64_t bytes = 0;
    std::uint32_t prev = 0;  // towards the most-recent end (0: this is the most recent)
    std::uint32_t next = 0;  // towards the least-recent end; in the free list, the next free node
    Value value{};
  };
  // 8 bytes: 8 slots a cache line. The tag (low 32 bits of mix64 of the key) gives the home slot
  // and filters probes without touching nodes; only a tag match reads the node's key.
  struct Slot {
    std::uint32_t tag = 0;
    std::uint32_t node = kNil;  // kNil: empty
  };

  class HookScope {
   public:
    explicit HookScope(bool& flag) : flag_(flag) { flag_ = true; }
    ~HookScope() { flag_ = false; }
    HookScope(const HookScope&) = delete;
    HookScope& operator=(const HookScope&) = delete;

   private:
    bool& flag_;
  };

  void check_not_in_hook(const char* what) const {
    if (in_hook_)
      throw std::logic_error(std::string("LruCache::") + what + " called from the removal hook");
  }

  static std::uint32_t tag_of(TileKey key) { return static_cast<std::uint32_t>(mix64(key.bits)); }

  // The slot holding key, or the empty slot that ends its probe sequence.
  std::size_t find_slot(TileKey key, std::uint32_t tag) const {
    for (std::size_t i = tag & mask_;; i = (i + 1) & mask_) {
      const Slot s = slots_[i];
      if (s.node == kNil || (s.tag == tag && nodes_[s.node].key == key)) return i;
    }
  }
  // The slot pointing at node n (which is in the table): compares node indices, not keys.
  std::size_t slot_of_node(std::uint32_t n) const {
    std::size_t i = tag_of(nodes_[n].key) & mask_;
    while (slots_[i].node != n) i = (i + 1) & mask_;
    return i;
  }

  // Backward-shift deletion: pull later members of the cluster into the hole when their home
  // does not lie cyclically in (hole, j], so every key stays reachable from its home slot.
  void erase_slot(std::size_t hole) {
    std::size_t j = hole;
    for (;;) {
      j = (j + 1) & mask_;
      const Slot s = slots_[j];
      if (s.node == kNil) break;
      if (((j - s.tag) & mask_) >= ((j - hole) & mask_)) {
        slots_[hole] = s;
        hole = j;
      }
    }
    slots_[hole].node = kNil;
  }

  void rehash(std::size_t new_slots) {
    std::vector<Slot> fresh(new_slots);
    const std::size_t m = new_slots - 1;
    for (const Slot& s : slots_) {
      if (s.node == kNil) continue;
      std::size_t i = s.tag & m;
      while (fresh[i].node != kNil) i = (i + 1) & m;
      fresh[i] = s;
    }
    slots_.swap(fresh);
    mask_ = m;
  }

  void grow_slab() {
    if (nodes_.size() > kMaxEntries) throw std::length_error("LruCache: more than 2^31-1 entries");
    nodes_.emplace_back();
    const auto n = static_cast<std::uint32_t>(nodes_.size() - 1);
    nodes_[n].next = free_;
    free_ = n;
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

  // Unlinks node n from table and list, charges counters, then hands it to the hook and recycles
  // it (also when the hook throws).
  void remove_node(std::uint32_t n, LruRemoval reason) {
    Node& node = nodes_[n];
    erase_slot(slot_of_node(n));
    unlink(n);
    --size_;
    bytes_ -= node.bytes;
    if (reason == LruRemoval::kEvicted || reason == LruRemoval::kShrunk) {
      ++stats_.evictions;
      stats_.evicted_bytes += node.bytes;
    }
    if (hook_) {
      HookScope scope(in_hook_);
      try {
        hook_(node.key, node.value, node.bytes, reason);
      } catch (...) {
        recycle(n);
        throw;
      }
    }
    recycle(n);
  }

  void recycle(std::uint32_t n) {
    Node& node = nodes_[n];
    node.value = Value{};
    node.bytes = 0;
    node.next = free_;
    free_ = n;
  }

  std::uint64_t capacity_ = 0;
  std::uint64_t bytes_ = 0;
  std::size_t size_ = 0;
  Hook hook_;
  std::vector<Node> nodes_;   // [0] is the list sentinel: next = most recent, prev = least recent
  std::uint32_t free_ = kNil;  // head of the free-node list
  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  LruStats stats_;
  bool in_hook_ = false;
};

}  // namespace vtsim
