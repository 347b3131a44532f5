#include "cache/page_pool.h"

#include <stdexcept>

namespace vtsim {

PagePool::PagePool(std::uint32_t slots, int layers, int lock_from_level, Hook hook,
                   std::unique_ptr<IReplacementPolicy> policy)
    : slot_(slots), lock_from_(lock_from_level), hook_(std::move(hook)), policy_(std::move(policy)) {
  if (slots == 0) throw std::invalid_argument("PagePool: at least one slot");
  if (layers < 1 || layers > 16) throw std::invalid_argument("PagePool: layers must be 1..16");
  full_mask_ = (1u << layers) - 1u;
  for (std::uint32_t s = slots; s-- > 0;) free_push(s);  // slot 0 first out
}

void PagePool::lru_unlink(std::uint32_t s) {
  Slot& S = slot_[s];
  if (S.prev != kNoSlot) slot_[S.prev].next = S.next;
  else lru_head_ = S.next;
  if (S.next != kNoSlot) slot_[S.next].prev = S.prev;
  else lru_tail_ = S.prev;
  S.prev = S.next = kNoSlot;
  S.in_lru = false;
}

void PagePool::lru_push_front(std::uint32_t s) {
  Slot& S = slot_[s];
  S.prev = kNoSlot;
  S.next = lru_head_;
  if (lru_head_ != kNoSlot) slot_[lru_head_].prev = s;
  else lru_tail_ = s;
  lru_head_ = s;
  S.in_lru = true;
}

void PagePool::lru_insert_ordered(std::uint32_t s) {
  // Walk from the least recent end past every page older than s; s goes just after (more recent
  // than) them.
  std::uint32_t after = lru_tail_;
  while (after != kNoSlot && older(slot_[after], slot_[s])) after = slot_[after].prev;
  if (after == kNoSlot) {
    lru_push_front(s);
    return;
  }
  Slot& S = slot_[s];
  S.prev = after;
  S.next = slot_[after].next;
  if (S.next != kNoSlot) slot_[S.next].prev = s;
  else lru_tail_ = s;
  slot_[after].next = s;
  S.in_lru = true;
}

void PagePool::order_add(std::uint32_t s) {
  if (!policy_) {
    lru_push_front(s);
    return;
  }
  policy_->admit(slot_[s].page.bits, 1);
  slot_[s].in_lru = true;
}

void PagePool::order_add_restored(std::uint32_t s) {
  policy_->restore(slot_[s].page.bits, 1);
  slot_[s].in_lru = true;
}

bool PagePool::pinned_page(const void* ctx, std::uint64_t key) {
  const auto* c = static_cast<const PinCtx*>(ctx);
  const std::uint32_t* s = c->pool->page_slot_.find(key);
  return s && c->pool->slot_[*s].last_used >= c->frame;
}

void PagePool::free_push(std::uint32_t s) {
  Slot& S = slot_[s];
  S = Slot{};
  S.next = free_head_;
  free_head_ = s;
  ++free_count_;
}

std::uint32_t PagePool::free_pop() {
  const std::uint32_t s = free_head_;
  if (s == kNoSlot) return kNoSlot;
  free_head_ = slot_[s].next;
  slot_[s].next = kNoSlot;
  --free_count_;
  return s;
}

void PagePool::evict(std::uint32_t s, Removal why) {
  Slot& S = slot_[s];
  const Removed r{S.page, s, S.mask, S.mask == full_mask_, S.sampled, S.last_used, why};
  if (S.in_lru) {
    if (policy_) {
      policy_->remove(S.page.bits);
      S.in_lru = false;
    } else {
      lru_unlink(s);
    }
  }
  page_slot_.erase(S.page.bits);
  --occupied_;
  if (r.complete) --complete_;
  if (why == Removal::kEvicted) {
    ++stats_.evictions;
    if (!S.sampled) ++stats_.evicted_unsampled;
  } else {
    ++stats_.partial_released;
  }
  S.mask = 0;
  S.sampled = false;
  S.last_used = kNever;
  if (hook_) hook_(r);
}

PagePool::Touch PagePool::touch(TileKey page, int frame) {
  Touch t;
  const std::uint32_t* ps = page_slot_.find(page.bits);
  if (!ps) return t;
  const std::uint32_t s = *ps;
  t.slot = s;
  Slot& S = slot_[s];
  if (S.state == State::victim) {  // rescue: the incoming page loses this slot
    t.rescued = true;
    t.lost = S.incoming;
    reservations_.erase(S.incoming.bits);
    --pending_count_;
    ++stats_.rescues;
    S.state = State::resident;
  }
  S.last_used = frame;
  S.seq = ++seq_;
  t.complete = S.mask == full_mask_;
  if (S.state == State::resident && !locked(S.page)) {
    if (policy_) {
      if (!S.in_lru) order_add_restored(s);
      policy_->hit(S.page.bits);
    } else {
      if (S.in_lru) lru_unlink(s);
      lru_push_front(s);
    }
  }
  return t;
}

std::uint32_t PagePool::reserve(TileKey page, int frame) {
  if (const std::uint32_t* r = reservations_.find(page.bits)) return *r;
  if (page_slot_.contains(page.bits)) throw std::logic_error("PagePool::reserve: the page is already in a slot");
  std::uint32_t s = free_pop();
  if (s != kNoSlot) {
    slot_[s].state = State::reserved_free;
  } else if (policy_) {
    const PinCtx ctx{this, frame};
    const std::uint64_t victim = policy_->evict(Pinned{&PagePool::pinned_page, &ctx});
    if (victim == kNoKey) {  // every page in the order is used this frame
      ++stats_.reserve_failures;
      return kNoSlot;
    }
    const std::uint32_t* vs = page_slot_.find(victim);
    if (!vs || slot_[*vs].state != State::resident || !slot_[*vs].in_lru)
      throw std::logic_error("PagePool::reserve: the policy chose a page that is not in its order");
    s = *vs;
    slot_[s].in_lru = false;
    slot_[s].state = State::victim;
    ++pending_count_;
  } else if (lru_tail_ != kNoSlot && slot_[lru_tail_].last_used < frame) {
    s = lru_tail_;
    lru_unlink(s);
    slot_[s].state = State::victim;
    ++pending_count_;
  } else {
    ++stats_.reserve_failures;
    return kNoSlot;
  }
  slot_[s].incoming = page;
  reservations_.put(page.bits, s);
  ++stats_.reservations;
  return s;
}

void PagePool::release(TileKey page) {
  const std::uint32_t* r = reservations_.find(page.bits);
  if (!r) return;
  const std::uint32_t s = *r;
  reservations_.erase(page.bits);
  Slot& S = slot_[s];
  switch (S.state) {
    case State::reserved_free:
      free_push(s);
      break;
    case State::victim:
      S.state = State::resident;
      --pending_count_;
      ++stats_.released_victims;
      if (policy_) order_add_restored(s);
      else lru_insert_ordered(s);
      break;
    case State::filling:
      evict(s, Removal::kReleased);
      free_push(s);
      break;
    case State::free:
    case State::resident:
      throw std::logic_error("PagePool::release: inconsistent reservation");
  }
}

PagePool::Commit PagePool::commit(TileKey page, int layer, int frame) {
  Commit c;
  const std::uint32_t* r = reservations_.find(page.bits);
  if (!r || layer < 0 || layer >= 16 || !(full_mask_ & (1u << layer))) return c;
  const std::uint32_t s = *r;
  Slot& S = slot_[s];
  if (S.state == State::victim) {
    --pending_count_;
    evict(s, Removal::kEvicted);
  }
  if (S.state == State::victim || S.state == State::reserved_free) {
    c.first_layer = true;
    S.state = State::filling;
    S.page = page;
    S.mask = 0;
    S.sampled = false;
    page_slot_.put(page.bits, s);
    ++occupied_;
  }
  S.mask |= 1u << layer;
  S.last_used = frame;
  S.seq = ++seq_;
  c.slot = s;
  if (S.mask == full_mask_) {
    c.complete = true;
    S.state = State::resident;
    reservations_.erase(page.bits);
    ++complete_;
    if (locked(page)) {
      ++locked_count_;
      locked_slots_.push_back(s);
    } else {
      order_add(s);
    }
  }
  return c;
}

std::uint32_t PagePool::slot_of(TileKey page) const {
  if (const std::uint32_t* s = page_slot_.find(page.bits)) return *s;
  if (const std::uint32_t* r = reservations_.find(page.bits)) return *r;
  return kNoSlot;
}

bool PagePool::resident(TileKey page) const {
  const std::uint32_t* s = page_slot_.find(page.bits);
  return s && slot_[*s].mask == full_mask_;
}

std::uint32_t PagePool::resident_mask(TileKey page) const {
  const std::uint32_t* s = page_slot_.find(page.bits);
  return s ? slot_[*s].mask : 0u;
}

int PagePool::last_used(TileKey page) const {
  const std::uint32_t* s = page_slot_.find(page.bits);
  return s ? slot_[*s].last_used : kNever;
}

std::uint32_t PagePool::used_within(int frame, int window) const {
  const int from = frame - window + 1;
  const auto in = [&](const Slot& S) { return S.last_used >= from && S.last_used <= frame; };
  std::uint32_t n = 0;
  if (policy_) {  // no list by recency: every slot
    for (const Slot& S : slot_) n += (S.state == State::resident || S.state == State::victim) && in(S);
    return n;
  }
  // The LRU list runs from the most recent page: stop at the first one used before the window.
  for (std::uint32_t s = lru_head_; s != kNoSlot && slot_[s].last_used >= from; s = slot_[s].next) n += in(slot_[s]);
  for (const std::uint32_t s : locked_slots_) n += in(slot_[s]);
  reservations_.for_each([&](std::uint64_t, std::uint32_t s) { n += slot_[s].state == State::victim && in(slot_[s]); });
  return n;
}

std::optional<TileKey> PagePool::complete_page(std::uint32_t slot) const {
  const Slot& x = slot_.at(slot);
  if ((x.state == State::resident || x.state == State::victim) && x.mask == full_mask_) return x.page;
  return std::nullopt;
}

std::vector<TileKey> PagePool::lru_order() const {
  std::vector<TileKey> out;
  for (std::uint32_t s = lru_tail_; s != kNoSlot; s = slot_[s].prev) out.push_back(slot_[s].page);
  return out;
}

}  // namespace vtsim
