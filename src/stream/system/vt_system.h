#pragma once
// Sparse virtual texturing as a streaming system (Yao 2011: id Tech 5 / RAGE; issue 5), the
// clipmap's sibling behind IStreamingSystem. docs/vt.md.
//
// Per frame:
//  1. begin_frame: the feedback buffer's samples give each a desired page at level
//     floor(lod + bias) (only visible, unoccluded samples exist: Yao 2011 §3.1); the wanted set is
//     those pages plus every coarser ancestor (the fallback chain a sample needs) plus the locked
//     coarsest levels. Demand per level, pool pressure and occupancy are measured for the policy.
//  2. apply_throttle: the residency policy's clamp (finest level requested and sampled), feedback
//     bias (requests) and sampling bias (what the screen samples).
//  3. emit_needs: wanted pages at or above the clamp that are in the pool are marked used (LRU by
//     last-used frame; a pending victim is rescued); reservations of pages no longer wanted are
//     released; the others are prioritised — coarse first, then by level gap (desired level to the
//     finest resident ancestor) × samples (RAGE) — and reserve a pool slot in that order, a
//     higher-priority page taking a lower one's reservation when the pool is short; pages with
//     a slot are requested (one Need per missing layer), the rest are throttled. Optional
//     prefetch of pages one or two levels finer than the desired ones into RAM (Unreal).
//  4. commit: an uploaded layer fills the reserved slot (the first one evicts the victim); a
//     complete page is mapped in the page table, and samples resolve to it from then on.
// Pop-in asks resident_levels: the page table's fallback from max(floor(lod + sampling bias),
// clamp) up, as the screen would sample.
//
// Complexity per frame: O(S + W log W) for S feedback samples and W wanted pages; resident_level
// O(1) amortised (memoised per page between page-table changes). Thread-safety: none (the frame
// loop). Invalidation: wanted() is rebuilt by begin_frame and emit_needs.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "cache/page_pool.h"
#include "cache/page_table.h"
#include "cache/vram_arena.h"
#include "stream/system/i_system.h"
#include "stream/system/system_caps.h"

namespace vtsim {

// The config's [vt] section.
struct VtConfig {
  std::uint32_t pool_pages = 1024;        // M: physical pool slots (RAGE-like: a 4096² texture of 128² pages)
  int locked_levels = 1;                  // coarsest levels requested first and never evicted
  int prefetch_finer_levels = 0;          // 0, 1 or 2 levels finer than desired into RAM (Unreal VT)
  int residency_window_frames = 15;       // a page used within this many frames counts as visible
  std::string pool_policy = "lru";        // pool replacement policy (replacement_policies()); "lru": the pool's own list
};

class VtSystem final : public IStreamingSystem {
 public:
  // The page size P is s.tile_size (even), its border B s.border. Throws std::invalid_argument for
  // impossible parameters (pool smaller than the locked levels, odd page size, ...); the replay
  // config names the field before it gets here (validate).
  VtSystem(const SystemSetup& s, const VtConfig& c);
  // What the systems' table (sim/run/systems.cpp) reads.
  using Config = VtConfig;  // the config's [vt] section
  // Cross-field checks, the pool's water marks included; throws InputError("config", "field '...': ...").
  static void validate(const SystemSetup& s, const VtConfig& c, const ThrottleParams& throttle);
  // The levels a store must hold: every level down to the first that is a single page.
  static int store_levels(const SystemSetup& s, const VtConfig& c);
  static constexpr std::string_view kStoreLevels = "a virtual texture needs every level down to a single page";
  // The real clock's VRAM: the physical page pool; the config field that sizes it.
  static VramArena vram_arena(const SystemSetup& s, const VtConfig& c, std::vector<std::uint32_t> layer_bytes,
                              std::uint64_t host_limit);
  static constexpr std::string_view kVramField = "vt.pool_pages";
  // Its name in the table (run.system) and what it can do.
  static constexpr char kName[] = "vt";
  static constexpr SystemCaps kCaps{.page_pool = true, .capacity = CapacityReport::page_pool, .mrc_level = "pool"};
  // The pool slots its replacement policy manages: the pool less the pages the locked levels
  // hold (those always hit); 0 when they fill it (validate refuses a pool smaller than them).
  static std::uint64_t unlocked_slots(std::uint64_t pool_pages, std::uint64_t locked_pages) {
    return pool_pages > locked_pages ? pool_pages - locked_pages : 0;
  }

  int num_levels() const override { return geo_.levels(); }
  int resident_level(std::int64_t u, std::int64_t v, int desired_level) const override;
  void resident_levels(const ViewSample* s, std::size_t n, std::int8_t* out) const override;
  // A span resolves at once when no sampling bias is set and its texel box lies in one page of
  // the level it samples (always, when spans are cut at pages: block = page size).
  void span_resident_levels(const ViewSpan* s, std::size_t n, std::int8_t* out) const override;
  void begin_frame(const SystemFrame& f) override;
  void missing_bytes_by_level(std::vector<std::uint64_t>& out) const override;
  int coarsest_clamp() const override;
  void apply_throttle(const ThrottleDecision& d) override;
  void emit_needs(std::vector<Need>& out) override;
  std::uint32_t throttled_needs() const override { return throttled_tiles_; }
  bool commit(TileKey key, int frame) override;
  bool accepts(TileKey key) const override;
  void record_page_table(std::vector<PageTableUpdate>* log) override { pt_log_ = log; }
  std::int64_t vram_slot(TileKey key) const override;
  void set_mark_sampled(bool on) override { mark_sampled_ = on; }
  bool uses_spans() const override { return true; }
  // build_wanted reads every sample under a feedback bias (levels move inside spans), and with a
  // page size that is not a power of two (spans are cut at 2^k-texel blocks, so many cross pages).
  bool wants_samples() const override { return bias_ != 0.0 || !geo_.pow2_page(); }
  double pool_occupancy() const override { return occupancy_; }
  double pool_pressure() const override { return pressure_; }
  void pool_demand(std::vector<std::uint64_t>& pages_by_level, std::uint64_t& slots) const override;
  std::vector<std::string> frame_counter_names() const override;
  void frame_counters(SystemCounters& out) const override;
  nlohmann::json stats_json() const override;
  std::uint64_t vram_evictions() const override { return evicted_layers_; }
  std::uint64_t vram_thrash() const override { return thrash_; }
  std::uint64_t evicted_unsampled_bytes() const override;
  void pool_pages(std::vector<std::pair<TileKey, std::uint32_t>>& out) const override;
  void record_pool_accesses(AccessLog* log) override { pool_log_ = log; }

  const VtGeometry& geometry() const { return geo_; }
  const PageTable& page_table() const { return pt_; }
  const PagePool& pool() const { return pool_; }
  int clamp() const { return clamp_; }
  double bias() const { return bias_; }

  // The wanted set of the last begin_frame/emit_needs, coarsest level first: pages and the
  // feedback samples that need them (directly or as their fallback).
  struct Wanted {
    TileKey page;
    std::uint32_t samples = 0;
    bool desired = false;  // a sample's own page (not only an ancestor or a locked page)
  };
  const std::vector<Wanted>& wanted() const { return wanted_; }
  // Per-frame counters of the last emit_needs (what the CSV columns hold).
  struct FrameCounts {
    std::uint32_t visible_pages = 0;     // wanted pages at or above the clamp
    std::uint32_t visible_resident = 0;  // of those, mapped (before this frame's commits)
    std::uint32_t throttled_pages = 0;   // wanted, not resident and not requested (clamp or no slot)
    std::uint32_t requested_pages = 0;   // with a reservation and a request this frame
    std::uint32_t prefetch_pages = 0;    // finer pages asked into RAM
    std::uint32_t rescues = 0;
  };
  const FrameCounts& frame_counts() const { return fc_; }

 private:
  void build_wanted();
  std::uint64_t page_priority(const Wanted& w) const;
  void on_removed(const PagePool::Removed& r);
  int resolve_from(int from, std::int64_t u, std::int64_t v) const;
  struct Memo;
  // The memo's entry for page (from, px, py), resolved if it was not (or is stale).
  const Memo& lookup(int from, std::int64_t px, std::int64_t py) const;

  SystemSetup s_;
  VtConfig c_;
  VtGeometry geo_;
  PageTable pt_;
  PagePool pool_;

  // Frame state.
  int frame_ = 0;
  const ViewBuffer* view_ = nullptr;
  const SpanBuffer* spans_ = nullptr;  // the same feedback in runs (null: per sample only)
  int clamp_ = 0;
  double bias_ = 0.0;          // feedback bias in force (requests)
  double built_bias_ = -1.0;   // bias the wanted set was built with
  double sample_bias_ = 0.0;   // sampling bias, levels
  int sample_shift_ = 0;       // the same rounded to whole levels (resident_level)
  bool mark_sampled_ = false;
  double occupancy_ = 0.0, pressure_ = 0.0;
  std::uint32_t throttled_tiles_ = 0;
  FrameCounts fc_;

  // Wanted set and its scratch (reused: no allocation in steady state).
  std::vector<Wanted> wanted_;
  std::vector<std::vector<Wanted>> by_level_;
  std::vector<Wanted> parents_, merged_;  // build_wanted's scratch
  std::vector<std::uint64_t> demand_by_level_;
  std::vector<std::uint64_t> missing_by_level_;
  PageMap<std::uint32_t> agg_;          // desired page -> index in desired_ (aggregation)
  // The desired pages of the last build_wanted in the order found, and what the screen samples
  // for each (span_resident_levels: resolved once per page-table generation, gen 0 = not yet).
  struct Desired {
    TileKey page;
    std::uint32_t samples = 0;
    mutable std::uint64_t gen = 0;
    mutable std::uint32_t slot = PageTable::kNoSlot;
    mutable int level = 0;
  };
  std::vector<Desired> desired_;
  struct Recent {
    std::uint64_t key = PageMap<int>::kEmpty;
    std::uint32_t page = 0;  // index in desired_
  };
  static constexpr int kRecentBits = 8;
  Recent recent_[1 << kRecentBits];
  // Per span of the last build_wanted that went span by span (span_data_: its spans, compared by
  // address only; null otherwise): the index of its page in desired_, kNoPage across pages.
  static constexpr std::uint32_t kNoPage = ~std::uint32_t{0};
  std::vector<std::uint32_t> span_page_;
  const ViewSpan* span_data_ = nullptr;
  PageMap<std::uint8_t> requested_;     // pages this system holds a reservation for
  struct Candidate {
    std::uint64_t priority;
    TileKey page;
  };
  std::vector<Candidate> candidates_;
  std::vector<std::uint8_t> got_slot_;
  std::vector<std::uint64_t> scratch_keys_;
  std::vector<ViewSample> expanded_;  // samples expanded from spans_ (build_wanted)

  // resident_level memo: page at the sampled level -> resolved level and slot.
  struct Memo {
    std::uint64_t key = PageMap<int>::kEmpty;
    std::uint64_t gen = 0;
    std::uint32_t slot = PageTable::kNoSlot;
    int level = 0;
  };
  static constexpr std::size_t kMemo = 4096;
  mutable std::vector<Memo> memo_;
  mutable Memo last_;
  std::uint64_t settings_gen_ = 1;  // bumped when clamp or sampling bias change

  // Counters.
  PageMap<int> evicted_at_;  // page -> frame it was evicted (thrash)
  std::uint64_t evicted_layers_ = 0, evicted_unsampled_layers_ = 0, thrash_ = 0, stale_commits_ = 0;
  std::uint64_t layer_commits_ = 0, pages_mapped_ = 0;
  std::uint64_t frame_start_mapped_ = 0, frame_start_evictions_ = 0, frame_start_baked_ = 0;
  // Per-frame series summaries (sum, max) for the "vt" summary section.
  struct Series {
    double sum = 0, max = 0;
    void add(double v) { sum += v, max = v > max ? v : max; }
  };
  Series s_visible_, s_visible_resident_, s_throttled_, s_pending_, s_occupancy_, s_pressure_, s_bias_, s_desired_;
  std::uint64_t frames_ = 0;
  std::uint64_t peak_occupied_ = 0;
  std::uint64_t peak_sparse_bytes_ = 0;
  double max_baked_frame_ = 0;
  std::uint64_t frame_start_rescues_ = 0;
  // Pool hits and misses (docs/metrics.md): wanted pages at or above the clamp, once a frame each.
  std::uint64_t pool_hits_ = 0;            // complete in a slot (a pending victim included: rescued)
  std::uint64_t pool_misses_ = 0;          // not complete: in no slot, reserved, or filling
  std::uint64_t pool_misses_no_slot_ = 0;  // of those, in no slot and with no reservation yet
  AccessLog* pool_log_ = nullptr;          // record_pool_accesses
  std::vector<PageTableUpdate>* pt_log_ = nullptr;  // record_page_table
};

}  // namespace vtsim
