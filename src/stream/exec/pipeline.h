#pragma once
// The request manager: one state machine per tile on its way disk -> RAM -> VRAM, the same for
// the simulated and the real clock (only the IExecutor differs). docs/pipeline.md.
//
//   needed -> queued -> submitted (reading -> decoding, inside the executor) -> in RAM
//          -> waiting_upload -> uploaded (resident; the record ends)
//   no longer needed: queued -> dropped (no cost); submitted -> executor.cancel(): not started ->
//          dropped (no cost), under way -> cancelling (result discarded or kept in RAM);
//          waiting_upload -> dropped (the tile stays in the RAM cache)
//   fault -> retried after a backoff, up to max_retries, then failed (not requested again for
//          failed_retry_s); the screen keeps the coarser level meanwhile.
//
// Per frame, in this order: begin_frame(t) (collect completions), set_needs(...) (diff against
// what is in flight; RAM hits skip IO and decode), dispatch() (submit queued work by priority up
// to the executor's capacity, then collect zero-time completions), take_uploads() (choose by
// priority within the upload budget; the caller commits them to VRAM).
//
// Produced tiles (TileSizes::produce, stream/exec/produce.h; docs/pipeline.md, "The produce
// stage"): needed -> queued -> submitted (producing, inside the executor) -> waiting_upload. At
// most PipelineConfig::produce_tiles_per_frame of them are submitted per frame, in priority order;
// the rest stay queued (counted: produce_deferred). They bypass the RAM cache both ways (no lookup,
// no insertion): VT Terrain Design renders them into the clipmap on the GPU, so a tile evicted from VRAM
// and needed again is produced again. Prefetch needs of produced tiles are ignored (prefetch fills
// RAM only).
//
// Complexity per frame: O(R + N log N) for R live requests and N needs; nothing when nothing is
// needed or in flight. Thread-safety: single-threaded (the frame loop); the executor may have
// threads of its own behind its interface.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "cache/lru_cache.h"
#include "cache/policy/access.h"
#include "cache/policy_cache.h"
#include "cache/need.h"
#include "core/tile_key.h"
#include "core/time.h"
#include "stream/exec/i_executor.h"
#include "stream/exec/pipeline_observer.h"
#include "stream/exec/produce.h"

namespace vtsim {

struct PipelineConfig {
  std::uint64_t ram_bytes = 256ull << 20;  // RAM cache capacity, bytes of decoded tiles
  int max_retries = 2;                     // retries of a faulted tile before it is marked failed
  int retry_backoff_frames = 2;            // frames to wait before a retry
  double failed_retry_s = 0.0;             // failed tiles are not requested again for this long; 0 = never
  bool cache_prefetched_on_cancel = true;  // a cancelled tile whose decode finished still enters RAM
  int thrash_frames = 60;                  // a miss within this many frames of an eviction is thrash
  std::string ram_policy = "lru";          // RAM replacement policy (replacement_policies()); "lru": LruCache
  int produce_tiles_per_frame = 0;         // produced jobs submitted per frame; 0 = unlimited (produce.tiles_per_frame)
};

// Sizes of a tile: what crosses the disk and what decode produces (RAM and VRAM bytes). A produced
// tile (produce.texels > 0) has disk_bytes 0 and its work instead of a read.
struct TileSizes {
  std::uint64_t disk_bytes = 0;
  std::uint64_t decoded_bytes = 0;
  ProduceWork produce{};  // texels == 0: read from the store
};
using TileSizer = std::function<TileSizes(TileKey)>;

// A tile ready for upload this frame, with its history for latency metrics.
struct UploadItem {
  TileKey key;
  std::uint64_t bytes = 0;           // decoded bytes uploaded
  int needed_frame = 0;              // first frame that needed it
  Ticks needed_time = 0;
  Ticks queue_ticks = 0;             // needed -> read start (pipeline queue + executor queue)
  Ticks io_ticks = 0;                // read start -> read end
  Ticks decode_wait_ticks = 0;       // read end -> decode start
  Ticks decode_ticks = 0;            // decode start -> decode end (a produced tile: production)
  Ticks ram_ticks = 0;               // in RAM -> chosen for upload (waiting for upload budget)
  bool ram_hit = false;              // came from the RAM cache: no IO, no decode
  bool produced = false;             // produced (io_ticks 0; decode_wait/decode = production queue/time)
  bool prefetched = false;           // the RAM entry was brought in by look-ahead prefetch
  std::shared_ptr<const TileData> data;  // real clock: the decoded tile to copy into VRAM
};

struct UploadBudget {
  std::uint64_t bytes = 0;  // 0 = unlimited
  int tiles = 0;            // 0 = unlimited
  // The link's copy time a frame (upload.per_tile_us > 0: the frame period), ticks; 0 = unlimited.
  // A tile costs per_tile_ticks + bytes / link_Bps (upload_ticks).
  Ticks link_ticks = 0;
  Ticks per_tile_ticks = 0;
  double link_Bps = 0.0;  // 0 = unlimited
};

// Counters, cumulative over the run (bytes and tiles).
struct PipelineCounters {
  std::uint64_t needs = 0;               // (tile, frame) demands seen by set_needs
  std::uint64_t requests = 0;            // demand requests created (first need of a non-resident tile)
  std::uint64_t ram_hits = 0, ram_misses = 0;  // at request creation
  std::uint64_t prefetch_requests = 0;
  std::uint64_t prefetch_hits = 0;       // demand requests served by a prefetched RAM entry
  std::uint64_t submitted = 0;           // jobs given to the executor
  std::uint64_t disk_bytes = 0, disk_reads = 0;          // all reads completed (incl. wasted)
  std::uint64_t prefetch_disk_bytes = 0;                  // of which look-ahead prefetch
  std::uint64_t decoded_bytes = 0, decodes = 0;
  std::uint64_t cancelled_queued = 0;    // dropped before any IO (pipeline or executor queue)
  std::uint64_t cancelled_after_read = 0;   // read paid, decode skipped or result unused
  std::uint64_t wasted_read_bytes = 0;   // disk bytes of reads whose tile was no longer needed
  std::uint64_t dropped_before_upload = 0;  // in RAM, no longer needed before its upload
  std::uint64_t uploads = 0, upload_bytes = 0;
  std::uint64_t faults = 0, retries = 0, failed_tiles = 0;
  std::uint64_t ram_evictions = 0, ram_evicted_bytes = 0;
  std::uint64_t fault_by_kind[8] = {};
  std::uint64_t ram_thrash = 0;          // RAM misses on tiles evicted within thrash_frames
  std::uint64_t disk_bytes_by_level[TileKey::kMaxLevels] = {};
  // The produce stage (none of the above disk, decode or RAM counters moves for a produced tile).
  std::uint64_t produce_requests = 0;    // demand requests created for produced tiles
  std::uint64_t produce_submitted = 0;   // produced jobs given to the executor (retries included)
  std::uint64_t produced = 0, produced_bytes = 0;  // produced tiles completed (ready), their bytes
  std::uint64_t produce_ns = 0;          // production time of the completed ones (decode_start -> decode_end), ns
  std::uint64_t produce_deferred = 0;    // (request, frame) pairs left queued by the production budget
  std::uint64_t produce_cancelled = 0;   // dropped before production started (no cost)
};

// A demand request that ended without its tile being uploaded: the survival analysis of latency
// counts it as censored at `end_time` (docs/metrics.md, "Latency"). A request still open at the
// run's end is censored there (Pipeline::open_demand_requests).
enum class Unserved : std::uint8_t { cancelled, failed, open_at_end, stale };
struct UnservedRequest {
  Ticks needed_time = 0;  // its first need (as UploadItem::needed_time)
  Ticks end_time = 0;     // when it stopped being needed (cancelled), was given up (failed), the run ended
  Unserved why = Unserved::cancelled;
};

// What a throttling policy may read: the backlog by level (bytes not yet resident).
struct Backlog {
  std::vector<std::uint64_t> bytes_by_level;   // queued + in flight + waiting upload, demand only
  std::vector<std::uint32_t> tiles_by_level;
};

// What the RAM cache holds per tile: the decoded data (real clock; null when simulated).
struct RamEntry {
  std::shared_ptr<const TileData> data;
  bool prefetched = false;  // brought in by look-ahead prefetch and not used since
};

class Pipeline {
 public:
  Pipeline(const PipelineConfig& cfg, IExecutor& exec, TileSizer sizer);

  void begin_frame(int frame, Ticks now);
  // `needs` is the complete list of tiles needed and not resident this frame (any order).
  void set_needs(const std::vector<Need>& needs);
  void dispatch();
  // Chooses uploads by priority within the budget (and removes them from the pipeline).
  void take_uploads(const UploadBudget& budget, std::vector<UploadItem>& out);
  // Uploads taken and not made (the engine's copy failed): back into the pipeline, waiting for
  // upload first in line, with their history and data, as if never taken (the upload counters
  // are taken back). A tile no longer needed at the next set_needs is dropped as usual.
  void return_uploads(std::vector<UploadItem>::iterator first, std::vector<UploadItem>::iterator last);

  // The caller evicted a resident tile from VRAM: nothing to do here (the RAM copy, if any, stays).
  bool in_ram(TileKey key) const { return ram_any_ ? ram_any_->contains(key) : ram_.contains(key); }
  bool is_failed(TileKey key) const;

  const PipelineCounters& counters() const { return counters_; }
  // The demand requests that ended unserved so far (cancelled, failed), in the order they ended.
  const std::vector<UnservedRequest>& unserved() const { return unserved_; }
  // Appends the demand requests still open (not cancelled) as censored at `end` (open_at_end).
  void open_demand_requests(Ticks end, std::vector<UnservedRequest>& out) const;
  std::size_t live_requests() const { return requests_.size(); }
  std::size_t queued() const;  // requests waiting in the pipeline's own queue (diagnostics; O(R))
  Backlog backlog(int num_levels) const;
  std::uint64_t ram_bytes_used() const { return ram_any_ ? ram_any_->bytes() : ram_.bytes(); }
  const std::string& ram_policy() const { return cfg_.ram_policy; }
  // Opt-in: from now on, every RAM lookup of a demand request (the lookups counted in
  // counters().ram_hits + ram_misses) appends an Access {tile key bits, decoded bytes} to `log`,
  // and begin_frame opens a frame in it. Null stops recording. `log` must outlive the recording.
  void record_ram_accesses(AccessLog* log) { ram_log_ = log; }
  // Opt-in: from now on the observer sees every request, job and unserved end
  // (pipeline_observer.h); null stops. It must outlive the observation.
  void set_observer(IPipelineObserver* observer) { observer_ = observer; }
  int frame() const { return frame_; }
  Ticks now() const { return now_; }

 private:
  enum class State : std::uint8_t { queued, submitted, cancelling, waiting_upload, backoff };
  struct Request {
    RequestId id = 0;
    TileKey key;
    State state = State::queued;
    bool prefetch = false;
    bool needed = false;        // needed in the current frame (set_needs marks)
    bool revived = false;       // cancelling, then needed again
    bool ram_hit = false, prefetched_entry = false;
    std::uint64_t priority = 0;
    TileSizes sizes;
    int needed_frame = 0;
    Ticks needed_time = 0;
    Ticks in_ram_time = 0;
    Ticks cancel_time = 0;      // when it last entered cancelling (no longer needed, its job running)
    int attempts = 0;
    int retry_frame = 0;
    JobResult timing;
    std::shared_ptr<const TileData> data;
  };
  void on_result(JobResult& r);
  void to_ram(Request& q, const std::shared_ptr<const TileData>& data, bool prefetched);
  void drop(TileKey key);
  // A demand request leaving unserved: recorded for the latency's censoring (prefetches are not requests).
  void end_unserved(const Request& q, Ticks end, Unserved why) {
    if (q.prefetch) return;
    unserved_.push_back({q.needed_time, end, why});
    if (observer_) observer_->on_unserved(q.key, end, why);
  }
  // The RAM tier: LruCache for "lru" (the fast path: a predictable branch, no virtual call),
  // PolicyCache for any other policy.
  const RamEntry* ram_get(TileKey key) { return ram_any_ ? ram_any_->get(key) : ram_.get(key); }
  bool ram_contains(TileKey key) const { return ram_any_ ? ram_any_->contains(key) : ram_.contains(key); }
  void record_ram(TileKey key, std::uint64_t bytes) {
    if (ram_log_) ram_log_->accesses.push_back(Access{key.bits, bytes});
  }

  PipelineConfig cfg_;
  IExecutor& exec_;
  TileSizer sizer_;
  LruCache<RamEntry> ram_;
  std::unique_ptr<PolicyCache<RamEntry>> ram_any_;  // set: the RAM tier is this one, ram_ stays empty
  AccessLog* ram_log_ = nullptr;
  IPipelineObserver* observer_ = nullptr;
  std::unordered_map<TileKey, Request, TileKeyHash> requests_;
  std::unordered_map<RequestId, TileKey> by_id_;
  std::unordered_map<TileKey, Ticks, TileKeyHash> failed_;  // key -> time it failed
  std::unordered_map<TileKey, int, TileKeyHash> ram_evicted_at_;  // key -> frame of its RAM eviction
  PipelineCounters counters_;
  std::vector<UnservedRequest> unserved_;
  RequestId next_id_ = 1;
  int frame_ = 0;
  Ticks now_ = 0;
  std::vector<JobResult> results_;
  std::vector<Request*> scratch_;
  int produced_this_frame_ = 0;  // produced jobs submitted since begin_frame (the production budget)
};

}  // namespace vtsim
