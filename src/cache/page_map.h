#pragma once
// A small open-addressing hash map from 64-bit page keys (TileKey::bits) to a plain value: the
// sparse storage behind the VT page table and page pool (docs/vt.md). A 2^26-texel virtual
// texture has 2^38 level-0 pages of 128 texels: only what is resident or wanted may cost memory.
//
// Linear probing over a power-of-two table kept at most half full; deletion by backward shift
// (no tombstones, probe lengths never degrade); hashing by mix64 (neighbouring page keys differ
// in low bits only). The key ~0 is reserved as the empty marker (a TileKey of layer 15, level 63:
// never a page key). Complexity: find/insert/erase expected O(1); growth doubles the table
// (amortised O(1)); memory 16 bytes per slot for an 8-byte value, 2-4 slots per entry.
// Thread-safety: none; const members are safe concurrently while nobody mutates. Invalidation:
// a pointer from find() is invalidated by insert and erase.
#include <cstdint>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/tile_key.h"

namespace vtsim {

template <class V>
  requires std::is_trivially_copyable_v<V>
class PageMap {
 public:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};

  PageMap() { reset(16); }

  V* find(std::uint64_t key) {
    for (std::size_t i = home(key);; i = (i + 1) & mask_) {
      if (slots_[i].key == key) return &slots_[i].value;
      if (slots_[i].key == kEmpty) return nullptr;
    }
  }
  const V* find(std::uint64_t key) const { return const_cast<PageMap*>(this)->find(key); }
  bool contains(std::uint64_t key) const { return find(key) != nullptr; }

  // Inserts or overwrites; returns a reference to the stored value.
  V& put(std::uint64_t key, V value) {
    if (key == kEmpty) throw std::invalid_argument("PageMap: the key ~0 is reserved");
    if ((size_ + 1) * 2 > slots_.size()) grow();
    std::size_t i = home(key);
    for (; slots_[i].key != kEmpty; i = (i + 1) & mask_)
      if (slots_[i].key == key) return slots_[i].value = value;
    slots_[i].key = key;
    slots_[i].value = value;
    ++size_;
    return slots_[i].value;
  }

  // Removes key; returns whether it was present.
  bool erase(std::uint64_t key) {
    std::size_t i = home(key);
    for (;; i = (i + 1) & mask_) {
      if (slots_[i].key == kEmpty) return false;
      if (slots_[i].key == key) break;
    }
    // Backward shift: pull later members of the probe run into the hole when their home allows.
    for (std::size_t j = (i + 1) & mask_;; j = (j + 1) & mask_) {
      if (slots_[j].key == kEmpty) break;
      const std::size_t h = home(slots_[j].key);
      // Move j into hole i unless h lies cyclically in (i, j].
      const bool stays = i <= j ? (h > i && h <= j) : (h > i || h <= j);
      if (stays) continue;
      slots_[i] = slots_[j];
      i = j;
    }
    slots_[i].key = kEmpty;
    --size_;
    return true;
  }

  void clear() {
    for (auto& s : slots_) s.key = kEmpty;
    size_ = 0;
  }
  std::size_t size() const { return size_; }
  std::size_t capacity_slots() const { return slots_.size(); }
  std::size_t memory_bytes() const { return slots_.size() * sizeof(Slot); }

  // Calls f(key, value&) for every entry (table order: deterministic for a given history).
  template <class F>
  void for_each(F&& f) {
    for (auto& s : slots_)
      if (s.key != kEmpty) f(s.key, s.value);
  }
  template <class F>
  void for_each(F&& f) const {
    for (const auto& s : slots_)
      if (s.key != kEmpty) f(s.key, s.value);
  }

 private:
  struct Slot {
    std::uint64_t key = kEmpty;
    V value{};
  };
  std::size_t home(std::uint64_t key) const { return static_cast<std::size_t>(mix64(key)) & mask_; }
  void reset(std::size_t n) {
    slots_.assign(n, Slot{});
    mask_ = n - 1;
    size_ = 0;
  }
  void grow() {
    std::vector<Slot> old = std::move(slots_);
    reset(old.size() * 2);
    for (const Slot& s : old)
      if (s.key != kEmpty) {
        std::size_t i = home(s.key);
        while (slots_[i].key != kEmpty) i = (i + 1) & mask_;
        slots_[i] = s;
        ++size_;
      }
  }

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

}  // namespace vtsim
