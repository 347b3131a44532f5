#include "stream/system/vt_system.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <iterator>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "core/error.h"

namespace vtsim {

namespace {

int lock_from(const VtGeometry& g, int locked_levels) { return g.levels() - std::max(0, locked_levels); }

// The pool's replacement policy: null for "lru" (the pool's own list, the fast path); its
// capacity is the slots the locked pages leave (at least one: a policy holds something).
std::unique_ptr<IReplacementPolicy> vt_pool_policy(const VtGeometry& g, const VtConfig& c) {
  if (c.pool_policy == "lru") return nullptr;
  std::uint64_t locked = 0;
  if (c.locked_levels >= 0 && c.locked_levels <= g.levels()) locked = g.coarsest_pages(c.locked_levels);
  const std::uint64_t capacity = std::max<std::uint64_t>(VtSystem::unlocked_slots(c.pool_pages, locked), 1);
  return make_replacement_policy(c.pool_policy, capacity);
}

}  // namespace

namespace {

[[noreturn]] void bad_vt_field(const std::string& key, const std::string& what) {
  throw InputError("config", "field '" + key + "': " + what);
}

}  // namespace

void VtSystem::validate(const SystemSetup& s, const VtConfig& c, const ThrottleParams& throttle) {
  if (s.tile_size < 2 || s.tile_size % 2 != 0)
    bad_vt_field("texture.tile_size", fmt::format("{}: a VT page must be even (a page lies inside one parent page)", s.tile_size));
  if (s.border > s.tile_size)
    bad_vt_field("texture.border", fmt::format("{} texels is larger than the page ({} texels)", s.border, s.tile_size));
  // Partial edge pages are allowed (docs/vt.md): no divisibility check on texture.width/height.
  try {
    const VtGeometry g(s.extent, s.tile_size, s.border);
    if (c.locked_levels > g.levels())
      bad_vt_field("vt.locked_levels", fmt::format("{} is more than the texture's {} levels", c.locked_levels, g.levels()));
    const std::uint64_t locked = g.coarsest_pages(c.locked_levels);
    if (c.pool_pages < locked)
      bad_vt_field("vt.pool_pages", fmt::format("{} pages is smaller than the {} locked levels ({} pages)", c.pool_pages,
                                                c.locked_levels, locked));
  } catch (const std::invalid_argument& e) {
    bad_vt_field("texture.tile_size", e.what());
  }
  // The policies read the pool's occupancy and pressure against these marks.
  if (throttle.low_water > throttle.high_water)
    bad_vt_field("throttle.low_water", fmt::format("{} is above throttle.high_water {}", throttle.low_water, throttle.high_water));
}

int VtSystem::store_levels(const SystemSetup& s, const VtConfig&) {
  return VtGeometry(s.extent, s.tile_size, s.border).levels();
}

VramArena VtSystem::vram_arena(const SystemSetup&, const VtConfig& c, std::vector<std::uint32_t> layer_bytes,
                               std::uint64_t host_limit) {
  return VramArena::for_pool(c.pool_pages, std::move(layer_bytes), host_limit);
}

void VtSystem::pool_pages(std::vector<std::pair<TileKey, std::uint32_t>>& out) const {
  out.clear();
  for (std::uint32_t s = 0; s < pool_.slots(); ++s)
    if (const std::optional<TileKey> page = pool_.complete_page(s)) out.emplace_back(*page, s);
}

VtSystem::VtSystem(const SystemSetup& s, const VtConfig& c)
    : s_(s),
      c_(c),
      geo_(s.extent, s.tile_size, s.border),
      pt_(geo_),
      pool_(c.pool_pages, s.layers, lock_from(geo_, c.locked_levels), {}, vt_pool_policy(geo_, c)),
      memo_(kMemo) {
  if (c.locked_levels < 0 || c.locked_levels > geo_.levels())
    throw std::invalid_argument("vt: locked levels must be in [0, levels]");
  if (geo_.coarsest_pages(c.locked_levels) > c.pool_pages)
    throw std::invalid_argument("vt: the pool is smaller than the locked levels");
  if (c.prefetch_finer_levels < 0 || c.prefetch_finer_levels > 2)
    throw std::invalid_argument("vt: prefetch_finer_levels must be 0, 1 or 2");
  if (c.residency_window_frames < 1) throw std::invalid_argument("vt: residency window must be >= 1 frame");
  pool_.set_hook([this](const PagePool::Removed& r) { on_removed(r); });
  by_level_.resize(static_cast<std::size_t>(geo_.levels()));
  demand_by_level_.assign(static_cast<std::size_t>(geo_.levels()), 0);
  missing_by_level_.assign(static_cast<std::size_t>(geo_.levels()), 0);
}

void VtSystem::on_removed(const PagePool::Removed& r) {
  const auto layers = static_cast<std::uint64_t>(std::popcount(r.mask));
  if (r.complete) {
    pt_.unmap(r.page);
    if (pt_log_) pt_log_->push_back({r.page, -1});
  }
  if (r.reason == PagePool::Removal::kEvicted) {
    evicted_layers_ += layers;
    if (!r.sampled) evicted_unsampled_layers_ += layers;
    evicted_at_.put(r.page.bits, frame_);
    if (evicted_at_.size() > 65536) {  // forget evictions too old to count as thrash
      scratch_keys_.clear();
      evicted_at_.for_each([&](std::uint64_t k, int f) {
        if (frame_ - f > s_.thrash_frames) scratch_keys_.push_back(k);
      });
      for (std::uint64_t k : scratch_keys_) evicted_at_.erase(k);
    }
  } else {
    evicted_unsampled_layers_ += layers;  // uploaded, never complete, never sampled
  }
}

int VtSystem::coarsest_clamp() const { return geo_.levels() - std::max(1, c_.locked_levels); }

// The wanted set: every sample's page at floor(lod + bias), every coarser ancestor, the locked
// levels. Built level by level from the finest: a level's pages are sorted and merged (samples
// summed), then their parents join the next level.
void VtSystem::build_wanted() {
  const int n = geo_.levels();
  for (auto& v : by_level_) v.clear();
  span_data_ = nullptr;  // set below when the spans are aggregated span by span
  const float bias = static_cast<float>(bias_);
  if (spans_ || view_) {
    // Aggregate samples into desired pages (desired_, in the order found): a run of samples on
    // one page costs one lookup, in a small direct-mapped cache of recent pages (one multiply;
    // rows repeat the row above's pages), else in the hash map.
    agg_.clear();
    desired_.clear();
    std::fill(std::begin(recent_), std::end(recent_), Recent{});
    std::uint64_t run_key = PageMap<int>::kEmpty;
    std::uint32_t run = 0;
    std::uint32_t run_page = 0;  // the run's page: its index in desired_
    const auto start = [&](std::uint64_t key) {
      run_key = key;
      Recent& r = recent_[(key * 0x9E3779B97F4A7C15ull) >> (64 - kRecentBits)];
      if (r.key == key) {
        run_page = r.page;
        return;
      }
      if (const std::uint32_t* k = agg_.find(key)) {
        run_page = *k;
      } else {
        run_page = static_cast<std::uint32_t>(desired_.size());
        agg_.put(key, run_page);
        Desired d;
        d.page.bits = key;
        desired_.push_back(d);
      }
      r = Recent{key, run_page};
    };
    const auto flush = [&] {
      if (run > 0) desired_[run_page].samples += run;
    };
    const std::int64_t W = geo_.extent().width, H = geo_.extent().height;
    const auto add_sample = [&](const ViewSample& s) {
      const int l = desired_level(s.lod + bias, n);
      const std::int64_t u = std::clamp<std::int64_t>(s.u, 0, W - 1), v = std::clamp<std::int64_t>(s.v, 0, H - 1);
      const std::uint64_t key = page_key(l, geo_.page_of(u >> l), geo_.page_of(v >> l)).bits;
      if (key == run_key) {
        ++run;
        return;
      }
      flush();
      start(key);
      run = 1;
    };
    // Spans (one page of one level each when cut at pages) stand for their samples when the bias
    // is zero: desired_level(lod + 0, n) = min(span.level, n − 1). Same runs, same order. A span
    // across a page edge goes sample by sample (expand_span).
    if (bias == 0.0f && spans_ && spans_->levels >= n) {
      span_page_.resize(spans_->spans.size());
      span_data_ = spans_->spans.data();
      std::uint32_t* sp_page = span_page_.data();
      for (const ViewSpan& sp : spans_->spans) {
        const int l = std::min(sp.level, n - 1);
        const std::int64_t u0 = std::clamp<std::int64_t>(sp.u_lo, 0, W - 1), u1 = std::clamp<std::int64_t>(sp.u_hi, 0, W - 1);
        const std::int64_t v0 = std::clamp<std::int64_t>(sp.v_lo, 0, H - 1), v1 = std::clamp<std::int64_t>(sp.v_hi, 0, H - 1);
        const std::int64_t px = geo_.page_of(u0 >> l), py = geo_.page_of(v0 >> l);
        if (px != geo_.page_of(u1 >> l) || py != geo_.page_of(v1 >> l)) {
          *sp_page++ = kNoPage;
          expanded_.clear();
          expand_span(*spans_, sp, expanded_);
          for (const ViewSample& s : expanded_) add_sample(s);
          continue;
        }
        const std::uint64_t key = page_key(l, px, py).bits;
        if (key != run_key) {
          flush();
          start(key);
          run = 0;
        }
        *sp_page++ = run_page;
        run += sp.count;
      }
    } else {
      // A biased LOD moves levels inside spans: per sample. The frame loop materialises them
      // while wants_samples(); on the frame the bias turns on they are expanded here.
      const std::vector<ViewSample>* all = view_ ? &view_->samples : nullptr;
      if (!all) {
        expanded_.clear();
        expand_spans(*spans_, 0, spans_->spans.size(), expanded_);
        all = &expanded_;
      }
      for (const ViewSample& s : *all) add_sample(s);
    }
    flush();
    // Each level's desired pages in the order found (what sorting them starts from).
    for (const Desired& d : desired_)
      by_level_[d.page.level()].push_back(Wanted{d.page, d.samples, true});
  }
  // Locked levels are always wanted.
  for (int l = std::max(0, n - c_.locked_levels); l < n; ++l) {
    const VtLevel& L = geo_.level(l);
    for (std::int64_t y = 0; y < L.pages_y; ++y)
      for (std::int64_t x = 0; x < L.pages_x; ++x) by_level_[static_cast<std::size_t>(l)].push_back(Wanted{page_key(l, x, y), 0, false});
  }
  // A level's pages: its desired and locked pages, sorted, merged with the parents of the finer
  // level's pages (which come out of that level in page order, below, without a sort), and
  // duplicates merged (samples summed). Sorting only the desired pages, not the parents too, gives
  // the same lists: a page's entries are merged whatever their order.
  const auto by_page = [](const Wanted& a, const Wanted& b) { return a.page < b.page; };
  parents_.clear();
  for (int l = 0; l < n; ++l) {
    auto& v = by_level_[static_cast<std::size_t>(l)];
    std::sort(v.begin(), v.end(), by_page);
    merged_.clear();
    std::merge(v.begin(), v.end(), parents_.begin(), parents_.end(), std::back_inserter(merged_), by_page);
    v.clear();
    for (const Wanted& w : merged_) {
      if (!v.empty() && v.back().page == w.page) {
        v.back().samples += w.samples;
        v.back().desired = v.back().desired || w.desired;
      } else {
        v.push_back(w);
      }
    }
    demand_by_level_[static_cast<std::size_t>(l)] = v.size();
    // The parents of v in page order (x, then y): v's pages of parent column x come as two runs,
    // even then odd child column, each sorted by y; merging the two by parent row sorts them.
    parents_.clear();
    if (l + 1 == n) break;
    for (std::size_t i = 0; i < v.size();) {
      const std::int64_t px = v[i].page.x() >> 1;
      std::size_t odd = i, end = i;
      while (odd < v.size() && v[odd].page.x() == 2 * px) ++odd;
      end = odd;
      while (end < v.size() && v[end].page.x() == 2 * px + 1) ++end;
      for (std::size_t a = i, b = odd; a < odd || b < end;) {
        const bool take_a = b >= end || (a < odd && (v[a].page.y() >> 1) <= (v[b].page.y() >> 1));
        const Wanted& w = v[take_a ? a++ : b++];
        parents_.push_back(Wanted{parent_page(w.page), w.samples, false});
      }
      i = end;
    }
  }
  wanted_.clear();
  for (int l = n - 1; l >= 0; --l) {
    const auto& v = by_level_[static_cast<std::size_t>(l)];
    wanted_.insert(wanted_.end(), v.begin(), v.end());
  }
  built_bias_ = bias_;
}

void VtSystem::begin_frame(const SystemFrame& f) {
  // Close the previous frame's page-table update count.
  const double baked_prev = static_cast<double>(pt_.counters().texels_written_baked - frame_start_baked_);
  max_baked_frame_ = std::max(max_baked_frame_, baked_prev);
  frame_ = f.frame;
  view_ = f.view;
  spans_ = f.spans;
  pool_.begin_frame(frame_);
  frame_start_mapped_ = pages_mapped_;
  frame_start_evictions_ = pool_.stats().evictions;
  frame_start_baked_ = pt_.counters().texels_written_baked;
  frame_start_rescues_ = pool_.stats().rescues;
  build_wanted();
  const auto slots = static_cast<double>(pool_.slots());
  pressure_ = static_cast<double>(wanted_.size()) / slots;
  // Visible residency (Unreal): pages used in the window of frames before this one.
  occupancy_ = static_cast<double>(pool_.used_within(frame_ - 1, c_.residency_window_frames)) / slots;
  std::fill(missing_by_level_.begin(), missing_by_level_.end(), 0);
  const auto per_layer = s_.tile_bytes_all_layers / static_cast<std::uint64_t>(s_.layers);
  for (const Wanted& w : wanted_) {
    const std::uint32_t have = pool_.resident_mask(w.page);
    const int missing = s_.layers - std::popcount(have);
    if (missing > 0) missing_by_level_[w.page.level()] += per_layer * static_cast<std::uint64_t>(missing);
  }
}

void VtSystem::missing_bytes_by_level(std::vector<std::uint64_t>& out) const { out = missing_by_level_; }

void VtSystem::pool_demand(std::vector<std::uint64_t>& pages_by_level, std::uint64_t& slots) const {
  pages_by_level = demand_by_level_;
  slots = pool_.slots();
}

void VtSystem::apply_throttle(const ThrottleDecision& d) {
  const int clamp = std::clamp(d.clamp, 0, coarsest_clamp());
  const double bias = std::clamp(std::isfinite(d.bias) ? d.bias : 0.0, 0.0, 63.0);
  const double sb = std::clamp(std::isfinite(d.sample_bias) ? d.sample_bias : 0.0, 0.0, 63.0);
  // The screen samples floor(lod + sb); with only the desired level floor(lod) at hand the shift is
  // rounded (docs/vt.md: the sampling bias is exact at whole levels).
  const int shift = static_cast<int>(std::floor(sb + 0.5));
  if (clamp != clamp_ || sb != sample_bias_) ++settings_gen_;
  clamp_ = clamp;
  sample_shift_ = shift;
  sample_bias_ = sb;
  bias_ = bias;
}

std::uint64_t VtSystem::page_priority(const Wanted& w) const {
  // RAGE: coarse first; within a level, the bigger the gap between the desired level and the
  // finest resident ancestor and the more samples wait for the page, the sooner.
  const int l = static_cast<int>(w.page.level());
  const PageTable::Resolved r = pt_.resolve(l, w.page.x(), w.page.y());
  const auto gap = static_cast<std::uint64_t>(r.level - l);
  return make_priority(static_cast<std::uint32_t>(l), (static_cast<std::uint64_t>(w.samples) + 1) * gap);
}

void VtSystem::emit_needs(std::vector<Need>& out) {
  if (built_bias_ != bias_) build_wanted();
  fc_ = FrameCounts{};
  throttled_tiles_ = 0;
  if (pool_log_) pool_log_->frame_start.push_back(pool_log_->accesses.size());
  const auto layers = static_cast<std::uint32_t>(s_.layers);

  // 1. Mark the wanted pages in the pool used (rescuing pending victims); collect the others.
  candidates_.clear();
  std::uint32_t desired = 0;
  for (const Wanted& w : wanted_) {
    const int l = static_cast<int>(w.page.level());
    if (l < clamp_) {
      if (!pool_.resident(w.page)) {
        ++fc_.throttled_pages;
        throttled_tiles_ += layers - static_cast<std::uint32_t>(std::popcount(pool_.resident_mask(w.page)));
      }
      continue;
    }
    desired += w.desired;
    ++fc_.visible_pages;
    if (pool_log_) pool_log_->accesses.push_back(Access{w.page.bits, 1});
    const PagePool::Touch t = pool_.touch(w.page, frame_);
    if (t.complete) {
      ++fc_.visible_resident;
      ++pool_hits_;
      continue;
    }
    ++pool_misses_;
    if (t.slot == PagePool::kNoSlot && !pool_.reserved(w.page)) ++pool_misses_no_slot_;
    candidates_.push_back(Candidate{page_priority(w), w.page});
  }
  fc_.rescues = static_cast<std::uint32_t>(pool_.stats().rescues - frame_start_rescues_);

  // 2. Reservations of pages no longer wanted (or now below the clamp) are released. Wanted at
  // or above the clamp: in its level's sorted list of the wanted set (a few requested pages are
  // searched there rather than every wanted page put in a hash set).
  scratch_keys_.clear();
  const auto by_page = [](const Wanted& a, const Wanted& b) { return a.page < b.page; };
  requested_.for_each([&](std::uint64_t k, std::uint8_t) {
    TileKey t;
    t.bits = k;
    const int l = static_cast<int>(t.level());
    const bool wanted = l >= clamp_ && l < geo_.levels() &&
                        std::binary_search(by_level_[static_cast<std::size_t>(l)].begin(),
                                           by_level_[static_cast<std::size_t>(l)].end(), Wanted{t, 0, false}, by_page);
    if (!wanted || !pool_.reserved(t)) scratch_keys_.push_back(k);
  });
  std::sort(scratch_keys_.begin(), scratch_keys_.end());  // deterministic release order
  for (std::uint64_t k : scratch_keys_) {
    TileKey t;
    t.bits = k;
    pool_.release(t);
    requested_.erase(k);
  }

  // 3. Slots in priority order; a page that finds none may take the reservation of a lower one
  // (not one already filling: its uploaded layers would be wasted).
  std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
    return a.priority != b.priority ? a.priority < b.priority : a.page < b.page;
  });
  std::size_t lowest = candidates_.size();  // candidates_[lowest..] were offered for stealing
  got_slot_.assign(candidates_.size(), 0);
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    const TileKey page = candidates_[i].page;
    std::uint32_t slot = pool_.reserve(page, frame_);
    while (slot == PagePool::kNoSlot && lowest > i + 1) {
      const TileKey low = candidates_[--lowest].page;  // not processed yet this frame
      if (!pool_.reserved(low) || pool_.resident_mask(low) != 0) continue;
      pool_.release(low);
      requested_.erase(low.bits);
      slot = pool_.reserve(page, frame_);
    }
    if (slot == PagePool::kNoSlot) continue;
    got_slot_[i] = 1;
    requested_.put(page.bits, 1);
  }
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    const TileKey page = candidates_[i].page;
    const std::uint32_t have = pool_.resident_mask(page);
    if (!got_slot_[i] || !pool_.reserved(page)) {
      ++fc_.throttled_pages;
      throttled_tiles_ += layers - static_cast<std::uint32_t>(std::popcount(have));
      continue;
    }
    ++fc_.requested_pages;
    for (std::uint32_t layer = 0; layer < layers; ++layer)
      if (!(have & (1u << layer)))
        out.push_back(Need{TileKey(layer, page.level(), page.x(), page.y()), candidates_[i].priority, false});
  }

  // 4. Prefetch (Unreal): pages one or two levels finer than a sample's own page, into RAM only.
  if (c_.prefetch_finer_levels > 0) {
    for (const Wanted& w : wanted_) {
      if (!w.desired) continue;
      const int l = static_cast<int>(w.page.level());
      for (int d = 1; d <= c_.prefetch_finer_levels && l - d >= std::max(0, clamp_); ++d) {
        const std::int64_t n = std::int64_t{1} << d;
        for (std::int64_t cy = w.page.y() * n; cy < (w.page.y() + 1) * n; ++cy)
          for (std::int64_t cx = w.page.x() * n; cx < (w.page.x() + 1) * n; ++cx) {
            if (!geo_.valid(l - d, cx, cy)) continue;
            const TileKey child = page_key(l - d, cx, cy);
            if (pool_.slot_of(child) != PagePool::kNoSlot) continue;
            ++fc_.prefetch_pages;
            const std::uint64_t prio = make_priority(static_cast<std::uint32_t>(l - d), w.samples);
            for (std::uint32_t layer = 0; layer < layers; ++layer)
              out.push_back(Need{TileKey(layer, child.level(), cx, cy), prio, true});
          }
      }
    }
  }

  // Per-frame series for the summary.
  ++frames_;
  s_visible_.add(fc_.visible_pages);
  s_visible_resident_.add(fc_.visible_pages ? static_cast<double>(fc_.visible_resident) / fc_.visible_pages : 1.0);
  s_throttled_.add(fc_.throttled_pages);
  s_pending_.add(static_cast<double>(requested_.size()));
  s_occupancy_.add(occupancy_);
  s_pressure_.add(pressure_);
  s_bias_.add(bias_);
  s_desired_.add(desired);
  peak_sparse_bytes_ = std::max<std::uint64_t>(peak_sparse_bytes_, pt_.sparse_bytes());
}

bool VtSystem::commit(TileKey key, int frame) {
  const TileKey page = page_key(static_cast<int>(key.level()), key.x(), key.y());
  const PagePool::Commit c = pool_.commit(page, static_cast<int>(key.layer()), frame);
  if (c.slot == PagePool::kNoSlot) {
    ++stale_commits_;
    return false;
  }
  ++layer_commits_;
  if (c.first_layer) {
    if (int* at = evicted_at_.find(page.bits)) {
      if (frame - *at <= s_.thrash_frames) ++thrash_;
      evicted_at_.erase(page.bits);
    }
  }
  if (c.complete) {
    pt_.map(page, c.slot);
    if (pt_log_) pt_log_->push_back({page, static_cast<std::int64_t>(c.slot)});
    requested_.erase(page.bits);
    ++pages_mapped_;
    peak_occupied_ = std::max<std::uint64_t>(peak_occupied_, pool_.occupied());
  }
  return true;
}

bool VtSystem::accepts(TileKey key) const {
  // PagePool::commit: a reserved page, a layer of the pool's mask.
  const int layer = static_cast<int>(key.layer());
  if (layer >= s_.layers) return false;
  return pool_.reserved(page_key(static_cast<int>(key.level()), key.x(), key.y()));
}

std::int64_t VtSystem::vram_slot(TileKey key) const {
  const std::uint32_t slot = pool_.slot_of(page_key(static_cast<int>(key.level()), key.x(), key.y()));
  return slot == PagePool::kNoSlot ? -1 : static_cast<std::int64_t>(slot);
}

int VtSystem::resolve_from(int from, std::int64_t u, std::int64_t v) const {
  u = std::clamp<std::int64_t>(u, 0, geo_.extent().width - 1);
  v = std::clamp<std::int64_t>(v, 0, geo_.extent().height - 1);
  const Memo& m = lookup(from, geo_.page_of(u >> from), geo_.page_of(v >> from));
  if (mark_sampled_ && m.slot != PageTable::kNoSlot) pool_.mark_sampled(m.slot);
  return m.level;
}

const VtSystem::Memo& VtSystem::lookup(int from, std::int64_t px, std::int64_t py) const {
  const std::uint64_t key = page_key(from, px, py).bits;
  const std::uint64_t gen = (pt_.generation() << 20) ^ settings_gen_;
  // Neighbouring samples mostly share a page: the last lookup answers them without hashing.
  if (key != last_.key || gen != last_.gen) {
    Memo& m = memo_[mix64(key) & (kMemo - 1)];
    if (m.key != key || m.gen != gen) {
      const PageTable::Resolved r = pt_.resolve(from, px, py);
      m.key = key;
      m.gen = gen;
      m.level = r.level;
      m.slot = r.slot;
    }
    last_ = m;
  }
  return last_;
}

int VtSystem::resident_level(std::int64_t u, std::int64_t v, int desired_level) const {
  // Only floor(lod) is known here: a fractional sampling bias is rounded (resident_levels below,
  // which sees each sample's lod, is exact).
  const int n = geo_.levels();
  return resolve_from(std::min(std::max(desired_level + sample_shift_, clamp_), n - 1), u, v);
}

void VtSystem::resident_levels(const ViewSample* s, std::size_t count, std::int8_t* out) const {
  // The screen samples floor(lod + sampling bias), no finer than the clamp (Yao 2007 §4-4), and the
  // page table falls back from there to the finest resident ancestor (Yao 2011 §3.2).
  const int n = geo_.levels();
  const auto sb = static_cast<float>(sample_bias_);
  for (std::size_t i = 0; i < count; ++i) {
    const int from = std::max(desired_level(s[i].lod + sb, n), std::min(clamp_, n - 1));
    out[i] = static_cast<std::int8_t>(resolve_from(from, s[i].u, s[i].v));
  }
}

void VtSystem::span_resident_levels(const ViewSpan* s, std::size_t count, std::int8_t* out) const {
  const int n = geo_.levels();
  const std::int64_t W = geo_.extent().width, H = geo_.extent().height;
  // Pop-in measured on the spans this frame's build_wanted aggregated one by one (the feedback
  // itself): a span not finer than the clamp samples from its desired page, whose index
  // build_wanted kept (kNoPage: across pages, as below). Each distinct page is then resolved once
  // per page-table generation, not looked up in the memo per span; the answers are the memo's.
  const bool known = s == span_data_ && count == span_page_.size();
  const std::uint64_t gen = pt_.generation() + 1;  // Desired::gen 0: not resolved
  for (std::size_t i = 0; i < count; ++i) {
    out[i] = -1;
    if (sample_bias_ != 0.0) continue;  // floor(lod + bias) may differ within the span
    const int l = std::min(s[i].level, n - 1);
    const int from = std::max(l, std::min(clamp_, n - 1));
    if (known && from == l) {
      if (span_page_[i] == kNoPage) continue;
      const Desired& d = desired_[span_page_[i]];
      if (d.gen != gen) {
        const Memo& m = lookup(from, d.page.x(), d.page.y());
        d.level = m.level;
        d.slot = m.slot;
        d.gen = gen;
      }
      if (mark_sampled_ && d.slot != PageTable::kNoSlot) pool_.mark_sampled(d.slot);
      out[i] = static_cast<std::int8_t>(d.level);
      continue;
    }
    const std::int64_t u0 = std::clamp<std::int64_t>(s[i].u_lo, 0, W - 1), u1 = std::clamp<std::int64_t>(s[i].u_hi, 0, W - 1);
    const std::int64_t v0 = std::clamp<std::int64_t>(s[i].v_lo, 0, H - 1), v1 = std::clamp<std::int64_t>(s[i].v_hi, 0, H - 1);
    if (geo_.page_of(u0 >> from) != geo_.page_of(u1 >> from) || geo_.page_of(v0 >> from) != geo_.page_of(v1 >> from))
      continue;
    out[i] = static_cast<std::int8_t>(resolve_from(from, u0, v0));  // marks the page sampled, as each sample would
  }
}

std::uint64_t VtSystem::evicted_unsampled_bytes() const {
  return evicted_unsampled_layers_ * (s_.tile_bytes_all_layers / static_cast<std::uint64_t>(s_.layers));
}

std::vector<std::string> VtSystem::frame_counter_names() const {
  return {"vt_visible_pages", "vt_visible_resident", "vt_pending", "vt_throttled_pages", "vt_pages_mapped",
          "vt_evictions",     "vt_rescues",          "vt_pool_occupancy", "vt_pool_pressure", "vt_pt_texels_baked"};
}

void VtSystem::frame_counters(SystemCounters& out) const {
  out.fill(0.0);
  out[0] = fc_.visible_pages;
  out[1] = fc_.visible_resident;
  out[2] = static_cast<double>(requested_.size());
  out[3] = fc_.throttled_pages;
  out[4] = static_cast<double>(pages_mapped_ - frame_start_mapped_);
  out[5] = static_cast<double>(pool_.stats().evictions - frame_start_evictions_);
  out[6] = fc_.rescues;
  out[7] = occupancy_;
  out[8] = pressure_;
  out[9] = static_cast<double>(pt_.counters().texels_written_baked - frame_start_baked_);
}

nlohmann::json VtSystem::stats_json() const {
  const double f = frames_ ? static_cast<double>(frames_) : 1.0;
  const auto series = [&](const Series& s) { return nlohmann::json{{"mean", s.sum / f}, {"max", s.max}}; };
  const auto& pc = pt_.counters();
  const auto& ps = pool_.stats();
  const double baked_last = static_cast<double>(pc.texels_written_baked - frame_start_baked_);
  return {{"levels", geo_.levels()},
          {"page_size", geo_.page_size()},
          {"border", geo_.border()},
          {"page_bytes", s_.tile_bytes_all_layers},
          {"pool_pages", pool_.slots()},
          {"pool_bytes", static_cast<std::uint64_t>(pool_.slots()) * s_.tile_bytes_all_layers},
          {"locked_levels", c_.locked_levels},
          {"locked_pages", geo_.coarsest_pages(c_.locked_levels)},
          {"lock_from_level", lock_from(geo_, c_.locked_levels)},
          {"page_table",
           {{"dense_entries", pt_.dense_entries()},
            {"dense_bytes", pt_.dense_bytes()},
            {"level0_entries", pt_.level0_entries()},
            {"sparse_bytes_peak", peak_sparse_bytes_},
            {"mapped_pages", pt_.mapped_pages()},
            {"maps", pc.maps},
            {"unmaps", pc.unmaps},
            {"entries_written", pc.entries_written},
            {"texels_written_baked", pc.texels_written_baked},
            {"texels_written_baked_per_frame", {{"mean", static_cast<double>(pc.texels_written_baked) / f},
                                                {"max", std::max(max_baked_frame_, baked_last)}}}}},
          {"pool",
           {{"evictions", ps.evictions},
            {"evicted_unsampled", ps.evicted_unsampled},
            {"rescues", ps.rescues},
            {"released_victims", ps.released_victims},
            {"partial_released", ps.partial_released},
            {"reservations", ps.reservations},
            {"reserve_failures", ps.reserve_failures},
            {"peak_occupied", peak_occupied_},
            {"resident_pages", pool_.resident_pages()},
            {"policy", c_.pool_policy},
            {"hits", pool_hits_},
            {"misses", pool_misses_},
            {"misses_no_slot", pool_misses_no_slot_}}},
          {"per_frame",
           {{"desired_pages", series(s_desired_)},
            {"visible_pages", series(s_visible_)},
            {"visible_resident_fraction", series(s_visible_resident_)},
            {"pending", series(s_pending_)},
            {"throttled_pages", series(s_throttled_)},
            {"pool_occupancy", series(s_occupancy_)},
            {"pool_pressure", series(s_pressure_)},
            {"bias", series(s_bias_)}}},
          {"layer_commits", layer_commits_},
          {"pages_mapped", pages_mapped_},
          {"stale_commits", stale_commits_},
          {"vram_evictions", evicted_layers_},
          {"vram_thrash", thrash_}};
}

}  // namespace vtsim
