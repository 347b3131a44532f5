#pragma once
// The physical page pool of virtual texturing (Yao 2011 §3.2 "显存贴图", the physical page
// texture): M slots, each holding one virtual page in every layer. docs/vt.md "Page pool".
//
// Lifecycle of a slot:
//   free -> reserved for an incoming page (at request time; no victim)
//   resident page -> pending eviction (chosen as the victim of an incoming page's reservation:
//                    still resident and sampled until the incoming page's first layer commits)
//   reserved/pending -> filling (the incoming page's first layer committed; the victim, if any,
//                    is evicted now) -> resident (every layer committed; the caller maps it)
// A victim needed again while its eviction is pending is *rescued*: it stays, and the incoming
// page's reservation is lost (the caller reserves again or drops the request). A reservation that
// is released (the page is no longer wanted) returns its victim to the LRU order, or frees a
// filling slot.
//
// Eviction order: least recently used by last-used frame (touch() marks a page used in a frame);
// only pages not used in the current frame can be victims. Pages of locked levels (the coarsest
// ones, `lock_from_level` and coarser) never enter the LRU and are never evicted. The pool never
// holds more than M pages: slots are the budget.
//
// Or a replacement policy of cache/policy (docs/vt.md, "Policies in the live caches"): without
// one the pool keeps the LRU list above (the "lru" fast path); with one, the policy holds the
// order of the same pages (complete, unlocked, not pending eviction) and is called: admit when a
// page completes, hit when a page in the order is touched, evict(pinned = used in the reserving
// frame) in reserve(), restore when a pending victim is rescued (then hit) or released back,
// remove if a page in the order leaves otherwise (never today), begin_frame from begin_frame().
// With the table's "lru" policy the victims equal the built-in list's as long as no pending
// victim is released back (release() reinserts it by last-used frame; the policy's restore makes
// it most recent): tests/test_vt_page_pool.cpp checks both.
//
// The one eviction hook (it must not throw): every page that leaves a slot (evicted by an
// incoming page, or a partial page whose reservation was released) leaves through the hook, once
// — the single place where its VRAM slot is freed and its page unmapped.
//
// Complexity: reserve, touch, commit, release O(1) expected (release of a victim reinserts it in
// LRU order, O(pages it passes) from the tail: in practice the other released victims), plus the
// policy's call when there is one. Memory: ~48 bytes per slot plus two hash maps (and the
// policy's per page). Thread-safety: none (the frame loop).
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "cache/page_map.h"
#include "cache/policy/i_replacement.h"
#include "core/tile_key.h"

namespace vtsim {

class PagePool {
 public:
  static constexpr std::uint32_t kNoSlot = ~std::uint32_t{0};
  static constexpr int kNever = -(1 << 30);  // last-used frame of a page never used

  enum class Removal : std::uint8_t {
    kEvicted,   // its slot went to an incoming page
    kReleased,  // a partial (filling) page whose reservation was released
  };
  struct Removed {
    TileKey page;
    std::uint32_t slot = kNoSlot;
    std::uint32_t mask = 0;      // layers it had resident
    bool complete = false;       // every layer resident (it was mapped)
    bool sampled = false;        // a sample resolved to it while resident
    int last_used = kNever;
    Removal reason = Removal::kEvicted;
  };
  using Hook = std::function<void(const Removed&)>;

  // slots >= 1; layers in [1, 16]; pages at level >= lock_from_level are locked. `policy`: the
  // eviction order (capacity in pages, unit sizes); null: the built-in LRU list.
  PagePool(std::uint32_t slots, int layers, int lock_from_level, Hook hook = {},
           std::unique_ptr<IReplacementPolicy> policy = nullptr);

  // Frame boundary: the policy, if any, learns the frame (frame numbers rise by one).
  void begin_frame(int frame) {
    if (policy_) policy_->begin_frame(frame);
  }
  bool has_policy() const { return policy_ != nullptr; }

  void set_hook(Hook hook) { hook_ = std::move(hook); }

  // Marks a page in a slot (resident, pending eviction or filling) used in `frame`: most recent
  // in the LRU order. A pending victim is rescued: it returns to the LRU order and the incoming
  // page it was reserved for loses its reservation (reported in `lost`; the caller reserves again
  // or drops that request). slot == kNoSlot when the page is in no slot.
  struct Touch {
    std::uint32_t slot = kNoSlot;
    bool rescued = false;
    TileKey lost;  // when rescued: the page whose reservation is gone
    bool complete = false;  // every layer resident (resident(page))
  };
  Touch touch(TileKey page, int frame);

  // Reserves a slot for a page not in the pool: a free slot, else the least recently used
  // unlocked page not used in `frame` (which becomes pending eviction). Returns kNoSlot when no
  // slot can be had (every resident page is locked, used this frame or already a victim). A page
  // that holds a reservation already keeps it (returns its slot).
  std::uint32_t reserve(TileKey page, int frame);
  // Drops a page's reservation: its victim returns to the LRU order (rescued without a reload),
  // a reserved free slot becomes free again, a filling slot is freed through the hook. No-op when
  // the page has no reservation.
  void release(TileKey page);

  // One layer of a reserved page arrived. The first layer evicts the slot's victim (hook). Returns
  // the slot and whether the page is now complete (every layer resident: the caller maps it); slot
  // kNoSlot when the page holds no reservation (nothing changes).
  struct Commit {
    std::uint32_t slot = kNoSlot;
    bool complete = false;
    bool first_layer = false;
  };
  Commit commit(TileKey page, int layer, int frame);

  // Observers (non-promoting).
  std::uint32_t slot_of(TileKey page) const;           // resident, filling or reserved; kNoSlot if none
  bool resident(TileKey page) const;                   // complete in a slot (victims included)
  bool reserved(TileKey page) const { return reservations_.contains(page.bits); }
  std::uint32_t resident_mask(TileKey page) const;     // layers present (0 when not in a slot)
  bool locked(TileKey page) const { return static_cast<int>(page.level()) >= lock_from_; }
  int last_used(TileKey page) const;                   // kNever if absent or never used

  std::uint32_t slots() const { return static_cast<std::uint32_t>(slot_.size()); }
  std::uint32_t free_slots() const { return free_count_; }
  std::uint32_t occupied() const { return occupied_; }        // slots holding a page (any layers)
  std::uint32_t resident_pages() const { return complete_; }  // complete pages
  std::uint32_t locked_pages() const { return locked_count_; }
  std::size_t reservations() const { return reservations_.size(); }
  std::uint32_t pending_evictions() const { return pending_count_; }
  // Resident pages (locked and pending victims included) used in frames [frame - window + 1,
  // frame]: O(those pages + locked pages + reservations).
  std::uint32_t used_within(int frame, int window) const;
  // Unlocked pages in eviction order, least recent first (diagnostics and tests; O(slots)).
  // Empty with a policy: its order is its own.
  std::vector<TileKey> lru_order() const;
  // The page complete in `slot` (resident, or a pending victim still mapped), if any. O(1).
  std::optional<TileKey> complete_page(std::uint32_t slot) const;

  // A sample resolved to this slot (for the wasted-upload metric).
  void mark_sampled(std::uint32_t slot) const { slot_[slot].sampled = true; }
  // Whether a sample resolved to the page in `slot` since it arrived. O(1).
  bool sampled(std::uint32_t slot) const { return slot_[slot].sampled; }

  struct Stats {
    std::uint64_t evictions = 0;           // pages evicted by incoming pages
    std::uint64_t evicted_unsampled = 0;   // of those, never sampled while resident
    std::uint64_t rescues = 0;             // victims needed again before their eviction
    std::uint64_t released_victims = 0;    // victims returned because the incoming page was no longer wanted
    std::uint64_t partial_released = 0;    // filling pages dropped (their uploads wasted)
    std::uint64_t reservations = 0;        // reservations made
    std::uint64_t reserve_failures = 0;    // reserve() calls that found no slot
  };
  const Stats& stats() const { return stats_; }

 private:
  enum class State : std::uint8_t { free, reserved_free, resident, victim, filling };
  struct Slot {
    TileKey page;               // page held (resident/victim/filling); for reserved_free: none
    TileKey incoming;           // page this slot is reserved for (reserved_free/victim)
    std::uint32_t mask = 0;     // layers of `page` present
    int last_used = kNever;
    std::uint64_t seq = 0;      // touch order within a frame (LRU tie-break)
    std::uint32_t prev = kNoSlot, next = kNoSlot;  // LRU list (resident unlocked) or free list
    State state = State::free;
    bool in_lru = false;
    mutable bool sampled = false;
  };

  void lru_unlink(std::uint32_t s);
  void lru_push_front(std::uint32_t s);
  void lru_insert_ordered(std::uint32_t s);  // by (last_used, seq), from the tail
  void free_push(std::uint32_t s);
  std::uint32_t free_pop();
  void evict(std::uint32_t s, Removal why);
  void order_add(std::uint32_t s);   // a complete unlocked page enters the order (admit)
  void order_add_restored(std::uint32_t s);  // a pending victim returns to the policy (restore)
  // evict(pinned): pages used in `frame` are pinned.
  struct PinCtx {
    const PagePool* pool;
    int frame;
  };
  static bool pinned_page(const void* ctx, std::uint64_t key);
  bool older(const Slot& a, const Slot& b) const {
    return a.last_used != b.last_used ? a.last_used < b.last_used : a.seq < b.seq;
  }

  std::vector<Slot> slot_;
  std::uint32_t full_mask_ = 1;
  int lock_from_ = 0;
  Hook hook_;
  PageMap<std::uint32_t> page_slot_;     // page held in a slot (resident, victim, filling) -> slot
  PageMap<std::uint32_t> reservations_;  // incoming page -> reserved slot (until complete)
  std::vector<std::uint32_t> locked_slots_;  // slots of locked pages (never freed)
  std::uint32_t lru_head_ = kNoSlot, lru_tail_ = kNoSlot;  // head: most recent
  std::uint32_t free_head_ = kNoSlot;
  std::uint32_t free_count_ = 0, occupied_ = 0, complete_ = 0, locked_count_ = 0, pending_count_ = 0;
  std::uint64_t seq_ = 0;
  Stats stats_;
  std::unique_ptr<IReplacementPolicy> policy_;  // null: the LRU list above
};

}  // namespace vtsim
