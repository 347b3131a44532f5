#pragma once
// The decode stage (Yao 2007 §4-3: decompression off the main thread): std::thread workers, separate
// from the IO pool's, check each record's XXH64 checksum (unless the IO pool already did: `verify`)
// and decode it with the tile's codec into a TileData, in priority order (lower first, then
// submission order). Decoded tiles' buffers are recycled (TileBufferPool), so a warm pool neither
// allocates nor page-faults per tile. docs/real-engine.md.
//
// Each accepted task yields exactly one DecodeResult through the sink, on a worker thread, unless
// cancel() removed it (still queued) or stop() dropped it (returned). The record buffer goes back
// to its pool when the task ends.
//
// State machine (std::atomic): running -> stopping -> stopped. stop() closes the queue, lets
// decodes under way finish and deliver, joins. Thread-safety: submit, cancel, queued, active from
// any thread; the sink is called with no pool lock held and must not throw. The TileStore must
// outlive the pool.
#include <atomic>
#include <functional>
#include <latch>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "stream/exec/io_pool.h"
#include "core/tile_data.h"
#include "stream/store/tile_store.h"
#include "stream/exec/wall_clock.h"
#include "stream/exec/work_queue.h"

namespace vtsim {

struct DecodeTask {
  RequestId id = 0;
  TileKey key;
  std::uint64_t priority = 0;
  RecordBuffer record;   // the bytes read: the payload is the first stored_bytes
  std::size_t size = 0;  // bytes of `record` that were read
};

// Free lists of decoded-tile buffers by size. A TileData made by decode_record with a pool hands
// its buffer back when the last reference goes (the RAM cache evicts it, say), from any thread.
// Thread-safe (one mutex); keeps at most `max_free` buffers of each size (more after reserve).
// acquire and release O(sizes).
class TileBufferPool : public std::enable_shared_from_this<TileBufferPool> {
 public:
  explicit TileBufferPool(std::size_t max_free = 256) : max_free_(max_free) {}
  std::unique_ptr<std::uint8_t[]> acquire(std::size_t bytes);
  void release(std::unique_ptr<std::uint8_t[]> buf, std::size_t bytes);
  // Allocates `count` buffers of `bytes` with their pages already mapped and written once, and keeps
  // up to that many free from then on: a decode into a fresh buffer page-faults on every 4 KiB it
  // writes, which on this project's VM cost 13 µs a page, 0.25 ms for a 136² RGB tile against a
  // 0.04 ms decode (docs/real-engine.md §7a). What the real clock reserves before its first frame.
  void reserve(std::size_t bytes, std::size_t count);
  std::size_t free_buffers(std::size_t bytes) const;

 private:
  struct SizeClass {
    std::size_t bytes = 0, max_free = 0;
    std::vector<std::unique_ptr<std::uint8_t[]>> free;
  };
  SizeClass& size_class(std::size_t bytes);  // under m_

  std::size_t max_free_;
  mutable std::mutex m_;
  std::vector<SizeClass> classes_;  // guarded by m_; a handful (one per layer format)
};

struct DecodeResult {
  RequestId id = 0;
  TileKey key;
  Fault fault = Fault::none;  // none, checksum (verify = true), decode_error or bad_record
  std::string error;          // names the file and the tile
  std::shared_ptr<const TileData> data;  // the decoded tile (null on a fault)
  Ticks decode_start = 0, decode_end = 0;
};

// What a worker does with one record (also called by benchmarks and calibration): checks the
// size (and, with `verify`, the XXH64 checksum) against the index, then decodes with the tile's
// codec into a TileData whose buffer comes from `buffers` (or the heap). Never throws; faults are
// reported in the result (no timestamps set).
DecodeResult decode_record(const TileStore& store, TileKey key, const std::uint8_t* record, std::size_t size,
                           bool verify, const std::shared_ptr<TileBufferPool>& buffers = {});

class DecodePool {
 public:
  enum class State : std::uint8_t { running, stopping, stopped };
  using Sink = std::function<void(DecodeResult&&)>;

  // verify: check each record's checksum before decoding (a mismatch is Fault::checksum); the
  // threaded executor's IO pool leaves it to this stage. warm: each worker decodes a tile of every
  // layer once before the constructor returns (warm_decode).
  DecodePool(const TileStore& store, int workers, const WallClock& clock, Sink sink, bool verify = true,
             bool warm = false);
  ~DecodePool();
  DecodePool(const DecodePool&) = delete;
  DecodePool& operator=(const DecodePool&) = delete;

  // false when stopping (the task is handed back untouched in `task`) or the id is queued.
  bool submit(DecodeTask& task);
  // true: the task was still queued and is dropped (no decode, no result).
  bool cancel(RequestId id);
  // Stops (idempotent): returns the ids of the tasks that were queued and will never decode.
  std::vector<RequestId> stop();

  // The decoded-tile buffers (TileBufferPool::reserve), before the first submit.
  void reserve_tiles(std::size_t bytes, std::size_t count) { tiles_->reserve(bytes, count); }
  std::size_t queued() const { return queue_.size(); }
  int active() const { return active_.load(std::memory_order_relaxed); }
  int workers() const { return static_cast<int>(workers_.size()); }
  int warmed() const { return warm_done_.load(std::memory_order_acquire); }  // workers whose warm_decode succeeded
  State state() const { return state_.load(std::memory_order_acquire); }

 private:
  void worker();
  // A worker's first decode of a codec pays for the codec's per-thread state (zstd's ZSTD_DCtx) and
  // the thread's first allocations: 0.4-4 ms on this project's VM against 0.04 ms warm
  // (docs/real-engine.md §7a). Reads (through the store's own descriptor) and decodes the coarsest
  // tile of each layer into a pool buffer and returns it. true: every layer decoded; errors are
  // left for the real request to report.
  bool warm_decode();

  const TileStore& store_;
  const WallClock& clock_;
  Sink sink_;
  const bool verify_;
  const bool warm_;
  std::latch warmed_;  // counts the workers still warming
  std::atomic<int> warm_done_{0};
  std::shared_ptr<TileBufferPool> tiles_ = std::make_shared<TileBufferPool>();
  WorkQueue<DecodeTask> queue_;
  std::atomic<int> active_{0};
  std::atomic<State> state_{State::running};
  std::mutex stop_m_;
  std::vector<std::thread> workers_;
};

}  // namespace vtsim
