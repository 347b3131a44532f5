#pragma once
// The real clock's executor (docs/real-engine.md): real O_DIRECT reads on the IO pool's threads,
// real checksum + decode on the decode pool's threads, completions stamped with the wall clock.
// Honours IExecutor's contract exactly like SimExecutor: one JobResult per submitted job unless
// cancel() returned true; results in completion order; collect() never blocks.
//
// A job's state machine (guarded by the executor's mutex; no flags):
//   io            queued in or being read by the IO pool
//   io_cancelled  cancel() came while it was being read: the read is paid, decode is skipped,
//                 the result is `cancelled`
//   decode        queued in or being decoded by the decode pool; cancel() while queued removes
//                 it (result `cancelled`, read paid), while decoding lets it finish (`ready`)
//   produce       a produced tile (TileJob::produce.texels > 0, with a producer), or a job the
//                 producer serves (ITileProducer::serves: the terrain's brush mips): queued in or
//                 being rendered by the production threads, never read; cancel() while queued
//                 drops it (true: no result), while producing lets it finish (`ready`). Without a
//                 producer, submitting a produced tile throws std::logic_error: it is never read
//                 from the store.
//   then its JobResult waits in the completion list until collect(until) with until >= its
//   completion time takes it.
// Executor lifecycle (std::atomic): running -> stopping -> stopped. shutdown() (also the
// destructor) refuses new jobs, completes queued jobs as `cancelled` with nothing read, lets reads
// and decodes under way finish (a read that finishes during shutdown skips its decode), queued
// productions complete as `cancelled`, productions under way finish, joins every thread; the
// results stay collectable.
//
// Lock order: executor mutex, then a pool's queue mutex; pools call back with no lock held.
// Thread-safety: every member may be called from any thread. submit/cancel/collect hold the
// executor mutex for O(log n) work: the frame loop never waits on IO or decode. The TileStore
// must outlive the executor.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <unordered_map>

#include "stream/exec/decode_pool.h"
#include "stream/exec/fault_layer.h"
#include "stream/exec/i_executor.h"
#include "stream/exec/i_producer.h"
#include "stream/exec/io_pool.h"
#include "stream/store/tile_store.h"
#include "stream/exec/wall_clock.h"
#include "stream/exec/work_queue.h"

namespace vtsim {

struct ThreadedExecutorConfig {
  int io_threads = 4;          // IO pool workers: reads in flight (io.threads)
  int decode_workers = 2;      // decode pool workers (decode.workers; 0 = hardware threads)
  std::size_t capacity = 64;   // jobs the pipeline may keep submitted (io.max_in_flight)
  bool direct = true;          // O_DIRECT (io.direct)
  IoEngine io_engine = IoEngine::psync;  // how the IO workers read (io.engine)
  int queue_depth = 16;        // io_uring: reads in flight per IO worker (io.queue_depth)
  int fail_ring_errno = 0;     // test hook: io_uring setup fails with this errno (IoPoolConfig)
  FaultConfig faults;          // injected faults (io.fault_rate, io.fault.*)
  // Decoded tiles to hold buffers for, mapped and written up front, bytes (ram.capacity_MiB: the RAM cache's
  // tiles, plus `capacity` in flight); spread over the layers as a page needs them, at most the
  // store's tiles. 0: none, every buffer is allocated on first use (and page-faults then).
  std::uint64_t tile_memory_bytes = 0;
  // Every IO and decode worker reads (and decodes) a tile before the constructor returns, as a
  // game's streaming threads have by the time it streams: on this project's VM a cold worker's
  // first read took 0.3-1.6 ms and its first decode 0.4-4 ms (io_pool.h, decode_pool.h). Not
  // through the fault layer; no results.
  bool warm = true;
  // Renders produced tiles (i_producer.h; not owned, must outlive the executor); null: a produced
  // tile is refused (submit throws).
  ITileProducer* producer = nullptr;
  int produce_workers = 2;     // production threads when producer is set (produce.workers; 1..1024)
};

class ThreadedExecutor final : public IExecutor {
 public:
  enum class State : std::uint8_t { running, stopping, stopped };

  ThreadedExecutor(const TileStore& store, const ThreadedExecutorConfig& cfg);
  // Production only (a system that stores nothing the tile path reads: the terrain in the real
  // clock, docs/produced.md "The real clock"): no store, no IO or decode threads; cfg.producer is
  // required (std::invalid_argument), and a job it neither produces nor serves throws
  // std::logic_error at submit. io_threads() and decode_workers() are 0.
  explicit ThreadedExecutor(const ThreadedExecutorConfig& cfg);
  ~ThreadedExecutor() override;
  // Decoded bytes of one tile of every layer of `store`.
  static std::uint64_t page_bytes(const TileStore& store);
  // How many tiles of each layer the constructor reserves buffers for (tile_memory_bytes): the
  // reserve is reserved_pages · page_bytes bytes, mapped and written before it returns.
  static std::uint64_t reserved_pages(const TileStore& store, const ThreadedExecutorConfig& cfg);
  ThreadedExecutor(const ThreadedExecutor&) = delete;
  ThreadedExecutor& operator=(const ThreadedExecutor&) = delete;

  Ticks now() const override { return clock_.now(); }
  std::size_t capacity() const override { return capacity_; }
  std::size_t in_flight() const override;  // submitted and not yet collected
  // Throws std::logic_error beyond capacity(), for a duplicate id, or after shutdown().
  void submit(const TileJob& job) override;
  bool cancel(RequestId id) override;
  // Moves every result completed at or before `until` (ticks of this executor's clock) to `out`.
  void collect(Ticks until, std::vector<JobResult>& out) override;

  // Sets the clock to 0 now (the replay's first frame). Throws std::logic_error with jobs in flight.
  void restart_clock();
  const WallClock& clock() const { return clock_; }
  void shutdown();
  State state() const { return state_.load(std::memory_order_acquire); }

  // Blocks until at least `n` results are waiting for collect() or `timeout` passes; true if they
  // are. For tests and tools, never the frame loop.
  bool wait_for_results(std::size_t n, std::chrono::milliseconds timeout);

  bool direct() const { return io_ && io_->direct(); }
  const std::string& direct_warning() const { return io_ ? io_->warning() : no_warning_; }
  IoEngine io_engine() const { return io_ ? io_->engine() : IoEngine::psync; }
  int io_queue_depth() const { return io_ ? io_->queue_depth() : 0; }
  const std::string& io_engine_warning() const { return io_ ? io_->engine_warning() : no_warning_; }
  int io_threads() const { return io_ ? io_->threads() : 0; }
  int reads_under_way() const { return io_ ? io_->active() : 0; }  // diagnostics and tests
  int decode_workers() const { return decode_ ? decode_->workers() : 0; }
  FaultLayer::Counts injected_faults() const { return faults_.injected(); }
  // The first error message of each fault kind seen (for the summary); empty if none.
  std::vector<std::string> fault_examples() const;
  // A tile whose reads faulted since its last success: how many times in a row, and the last
  // fault's kind and message. A tile that faulted more than the pipeline's max_retries times in a
  // row is one it marked failed. Sorted by key (deterministic order for the summary).
  struct TileFaults {
    TileKey key;
    std::uint32_t in_a_row = 0;
    Fault fault = Fault::none;
    std::string error;
  };
  std::vector<TileFaults> faulted_tiles() const;

 private:
  enum class JobState : std::uint8_t { io, io_cancelled, decode, produce };
  struct Job {
    TileJob job;
    JobState state = JobState::io;
    JobResult result;
  };
  void on_read(ReadResult&& r);
  void on_decoded(DecodeResult&& r);
  void produce_loop();
  // Completes a job (caller holds m_): stamps the completion time, queues the result.
  void finish(std::unordered_map<RequestId, Job>::iterator it, JobOutcome outcome, Fault fault,
              const std::string& error);

  void start_producers(const ThreadedExecutorConfig& cfg);

  const std::string no_warning_;
  WallClock clock_;
  FaultLayer faults_;
  std::size_t capacity_;
  std::atomic<State> state_{State::running};
  mutable std::mutex m_;
  std::condition_variable done_cv_;
  std::unordered_map<RequestId, Job> jobs_;   // in the pools; guarded by m_
  std::deque<JobResult> done_;                // completed, in completion order; guarded by m_
  std::vector<std::string> fault_examples_;   // guarded by m_
  std::unordered_map<TileKey, TileFaults, TileKeyHash> faulted_;  // guarded by m_; erased on a success
  std::unique_ptr<DecodePool> decode_;        // made before io_: reads hand over to it; null without a store
  std::unique_ptr<IoPool> io_;                // null without a store
  ITileProducer* producer_ = nullptr;
  WorkQueue<TileJob> produce_q_;              // produced tiles not yet started
  std::vector<std::thread> producers_;        // started last, joined by shutdown()
};

}  // namespace vtsim
