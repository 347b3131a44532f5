#pragma once
// The RAM tier under any replacement policy of cache/policy (docs/cache.md, "Policies in the live
// caches"): the same contract as LruCache (lru_cache.h) for what the pipeline calls — get, peek,
// contains, bytes_of, insert, erase, clear, set_capacity, the removal hook with its LruRemoval
// reasons, LruStats — with the order kept by an IReplacementPolicy instead of a built-in list.
// LruCache stays the "lru" fast path; with the table's "lru" policy this cache makes the same
// hits, misses and removal-hook calls in the same order (tested in tests/test_policy_cache.cpp).
//
// Division of labour (i_replacement.h): this cache holds key -> (value, bytes), the bytes held
// and the capacity; the policy holds the order. insert admits, then evicts with the entry being
// inserted pinned (the policy never picks it); a replaced key is removed, then admitted again; get is a
// hit; erase, and the replaced value, remove; capacity evictions and set_capacity ask evict().
// clear() evicts in the policy's order and then starts the policy afresh (no ghost history).
//
// Differences from LruCache: during an insert's evictions the entry being inserted is not in
// place yet (peek() does not see it, size() does not count it); no reserve(), probe_stats() or
// lru_key(). Hooks run with the entry already gone, under the same rules: get, insert, erase,
// clear, set_capacity or set_hook from the hook throw std::logic_error; if a hook throws, the
// entry stays removed and the operation stops there with the cache consistent and within
// capacity (an insert whose eviction hook throws does not insert its entry).
//
// Complexity: get, peek, contains, erase expected O(1) plus the policy's O(1) call (one virtual
// call); insert expected O(1) plus O(1) per entry evicted (amortised over table growth); clear
// O(size). Memory: one std::unordered_map node per entry (key, bytes, Value: ~56 bytes with an
// 8-byte Value, plus the bucket array) plus the policy's own per key. Thread-safety: none (one
// owner). Invalidation: a pointer from get()/peek() stays valid until its entry leaves (node-based
// map).
#include <concepts>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_map>
#include <utility>

#include "cache/lru_cache.h"
#include "cache/policy/i_replacement.h"
#include "core/tile_key.h"

namespace vtsim {

template <class Value>
  requires std::default_initializable<Value> && std::is_nothrow_move_constructible_v<Value> &&
           std::is_nothrow_move_assignable_v<Value>
class PolicyCache {
 public:
  using Hook = std::function<void(TileKey key, Value& value, std::uint64_t bytes, LruRemoval reason)>;

  // `policy`: a name of replacement_policies(); throws std::invalid_argument (with "did you
  // mean") for another.
  PolicyCache(std::string_view policy, std::uint64_t capacity_bytes, Hook hook = {})
      : name_(policy), capacity_(capacity_bytes), hook_(std::move(hook)),
        policy_(make_replacement_policy(policy, capacity_bytes)) {}
  PolicyCache(const PolicyCache&) = delete;
  PolicyCache& operator=(const PolicyCache&) = delete;

  void set_hook(Hook hook) {
    check_not_in_hook("set_hook");
    hook_ = std::move(hook);
  }

  // Promoting lookup (a hit for the policy). Counts a hit or a miss.
  Value* get(TileKey key) {
    check_not_in_hook("get");
    auto it = map_.find(key.bits);
    if (it == map_.end()) {
      ++stats_.misses;
      return nullptr;
    }
    ++stats_.hits;
    policy_->hit(key.bits);
    return &it->second.value;
  }
  const Value* peek(TileKey key) const {
    auto it = map_.find(key.bits);
    return it == map_.end() ? nullptr : &it->second.value;
  }
  Value* peek(TileKey key) {
    auto it = map_.find(key.bits);
    return it == map_.end() ? nullptr : &it->second.value;
  }
  bool contains(TileKey key) const { return map_.contains(key.bits); }
  std::uint64_t bytes_of(TileKey key) const {
    auto it = map_.find(key.bits);
    return it == map_.end() ? 0 : it->second.bytes;
  }

  // As LruCache::insert: rejects an entry larger than the capacity (nothing changes); a present
  // key's old value leaves first (kReplaced); the policy's victims leave (kEvicted) until it fits.
  LruInsert insert(TileKey key, Value value, std::uint64_t bytes) {
    check_not_in_hook("insert");
    if (bytes > capacity_) {
      ++stats_.rejected;
      return LruInsert::kRejected;
    }
    const bool replaced = map_.contains(key.bits);
    if (replaced) {
      policy_->remove(key.bits);
      remove_entry(key.bits, LruRemoval::kReplaced);
    }
    // Admit first, then evict with the incoming key pinned: the order the interface states
    // (i_replacement.h) and the offline simulator uses, so ARC adapts on the key that missed.
    policy_->admit(key.bits, bytes);
    try {
      while (bytes > capacity_ - bytes_) evict_one(LruRemoval::kEvicted, key.bits);
    } catch (...) {
      policy_->remove(key.bits);  // a hook threw: the entry is not inserted
      throw;
    }
    map_.emplace(key.bits, Entry{std::move(value), bytes});
    bytes_ += bytes;
    ++stats_.inserts;
    if (replaced) ++stats_.replacements;
    return replaced ? LruInsert::kReplaced : LruInsert::kInserted;
  }

  bool erase(TileKey key) {
    check_not_in_hook("erase");
    if (!map_.contains(key.bits)) return false;
    policy_->remove(key.bits);
    remove_entry(key.bits, LruRemoval::kErased);
    return true;
  }

  // Removes every entry through the hook (kCleared) in the policy's eviction order, then starts
  // the policy afresh. Keeps the counters.
  void clear() {
    check_not_in_hook("clear");
    while (!map_.empty()) evict_one(LruRemoval::kCleared);
    policy_ = make_replacement_policy(name_, capacity_);
  }

  void set_capacity(std::uint64_t capacity_bytes) {
    check_not_in_hook("set_capacity");
    while (bytes_ > capacity_bytes) evict_one(LruRemoval::kShrunk);
    capacity_ = capacity_bytes;
    policy_->set_capacity(capacity_bytes);
  }

  // Frame boundary, passed on to the policy (policies that age by frames read it).
  void begin_frame(int frame) { policy_->begin_frame(frame); }

  std::size_t size() const { return map_.size(); }
  bool empty() const { return map_.empty(); }
  std::uint64_t bytes() const { return bytes_; }
  std::uint64_t capacity() const { return capacity_; }
  const LruStats& stats() const { return stats_; }
  void reset_stats() { stats_ = {}; }
  const std::string& policy_name() const { return name_; }

 private:
  struct Entry {
    Value value;
    std::uint64_t bytes = 0;
  };

  void check_not_in_hook(const char* what) const {
    if (in_hook_) throw std::logic_error(std::string("PolicyCache::") + what + " called from the removal hook");
  }

  // The policy's victim leaves. Every cached key is in the policy and nothing is pinned, so
  // evict() finds one while the map is not empty.
  static bool is_incoming(const void* ctx, std::uint64_t k) { return k == *static_cast<const std::uint64_t*>(ctx); }
  void evict_one(LruRemoval reason, std::uint64_t incoming = kNoKey) {
    const std::uint64_t k = policy_->evict(Pinned{is_incoming, &incoming});
    if (k == kNoKey || !map_.contains(k))
      throw std::logic_error("PolicyCache: policy '" + name_ + "' returned no cached key to evict");
    remove_entry(k, reason);
  }

  // Takes the entry out of the map (the policy has already forgotten it), settles sizes and
  // counters, then hands the value to the hook.
  void remove_entry(std::uint64_t k, LruRemoval reason) {
    auto it = map_.find(k);
    Value value = std::move(it->second.value);
    const std::uint64_t b = it->second.bytes;
    map_.erase(it);
    bytes_ -= b;
    if (reason == LruRemoval::kEvicted || reason == LruRemoval::kShrunk) {
      ++stats_.evictions;
      stats_.evicted_bytes += b;
    }
    if (hook_) {
      RemovalHookScope scope(in_hook_);
      TileKey key;
      key.bits = k;
      hook_(key, value, b, reason);
    }
  }

  std::string name_;
  std::uint64_t capacity_ = 0;
  std::uint64_t bytes_ = 0;
  Hook hook_;
  std::unique_ptr<IReplacementPolicy> policy_;
  std::unordered_map<std::uint64_t, Entry> map_;
  LruStats stats_;
  bool in_hook_ = false;
};

}  // namespace vtsim
