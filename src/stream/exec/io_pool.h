#pragma once
// The IO thread pool (Yao 2007 §4-3: disk IO off the main thread, unbuffered, cluster-aligned):
// std::thread workers read tile records from a TileStore's file on a descriptor opened with
// O_DIRECT, into 4 KiB-aligned buffers, at the store's 4 KiB-aligned offsets, for the store's
// 4 KiB-rounded read sizes — so every read is legal under O_DIRECT. docs/real-engine.md.
//
// Two engines (IoPoolConfig::engine, config io.engine), the same threads and queue in front:
//  - psync: each worker has one `pread` in flight (as fio's psync engine): reads in flight <= threads.
//  - io_uring: each worker owns an io_uring (liburing) with up to `queue_depth` reads in flight
//    (IORING_OP_READ_FIXED into buffers registered with io_uring_register_buffers, on the file
//    registered with io_uring_register_files): reads in flight <= threads x queue_depth. A worker
//    sleeps in io_uring_wait_cqe; an eventfd read sits in its ring so that a submit (or stop) wakes
//    it while its reads are under way. Where the kernel has no io_uring or a seccomp filter refuses
//    it (io_uring_queue_init fails: ENOSYS, EPERM...), the pool reads with psync and engine_warning()
//    says why.
//
// O_DIRECT policy: checked once, at construction (open_for_read probes one aligned read); where
// the filesystem refuses it (EINVAL at the switch or at the probe), the pool reads through the page
// cache and says why in warning(). Every read is still aligned, so nothing else changes.
//
// Requests wait in a priority queue (lower value first, then submission order); cancel() removes
// a queued request (a request a worker has taken is under way: its result comes, as with psync).
// With IoPoolConfig::verify each record's XXH64 checksum is checked on the IO worker as it arrives;
// the threaded executor turns that off and has the decode worker check it instead (where the
// simulated clock finds a corrupt record too): on a 2-core machine with a 1.2 GB/s device the
// checksum on the IO workers cost 10-15 % of the read bandwidth (docs/real-engine.md §8), since
// the kernel's side of every O_DIRECT read needs the same cores. A read's faults come from an
// optional FaultLayer (EIO, short read, corrupted payload, slow), applied identically by both
// engines (prepare_read / finish_read); a real EIO or short count from a completion is the same
// fault as from pread.
// Each accepted request yields exactly one ReadResult through the sink, on a worker thread,
// unless cancel() removed it or stop() dropped it (stop returns those).
//
// State machine (std::atomic): running -> stopping -> stopped. stop() closes the queue (queued
// requests are returned, not read), lets reads under way finish and deliver their results (an
// injected slow read's wait is cut short: its io_uring timeout is removed), and joins the
// workers; the destructor stops. Each io_uring worker's sleep state is a std::atomic (busy ->
// idle, set before its last look at the queue; a submit takes idle -> busy and writes the
// eventfd). Thread-safety: submit, cancel, queued, active from any thread; the sink is called with
// no pool lock held and must not throw. The TileStore and the FaultLayer must outlive the pool.
#include <atomic>
#include <functional>
#include <latch>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "stream/store/aligned_io.h"
#include "stream/exec/fault_layer.h"
#include "stream/exec/i_executor.h"
#include "stream/exec/io_engine.h"
#include "stream/store/tile_store.h"
#include "stream/exec/wall_clock.h"
#include "stream/exec/work_queue.h"

namespace vtsim {

// A 4 KiB-aligned record buffer from a BufferPool, returned to it on destruction (no allocation
// and no zeroing per read once the pool is warm): its own heap buffer, or a slot of the pool's
// arena (in_arena(): memory registered with an io_uring). Move-only.
class BufferPool;
class RecordBuffer {
 public:
  RecordBuffer() = default;
  RecordBuffer(AlignedBuffer buf, std::shared_ptr<BufferPool> owner) : buf_(std::move(buf)), owner_(std::move(owner)) {}
  RecordBuffer(std::uint8_t* slot, std::shared_ptr<BufferPool> owner) : slot_(slot), owner_(std::move(owner)) {}
  ~RecordBuffer();
  RecordBuffer(RecordBuffer&& o) noexcept;
  RecordBuffer& operator=(RecordBuffer&& o) noexcept;
  RecordBuffer(const RecordBuffer&) = delete;
  RecordBuffer& operator=(const RecordBuffer&) = delete;

  std::uint8_t* data() { return slot_ ? slot_ : buf_.data(); }
  const std::uint8_t* data() const { return slot_ ? slot_ : buf_.data(); }
  std::size_t capacity() const;
  bool in_arena() const { return slot_ != nullptr; }

 private:
  void give_back();
  AlignedBuffer buf_;              // a heap buffer, or empty
  std::uint8_t* slot_ = nullptr;   // an arena slot of owner_, or null
  std::shared_ptr<BufferPool> owner_;
};

// Free list of equal-size aligned buffers. Thread-safe (one mutex). Keeps at most `max_free`.
// An arena pool (BufferPool::arena) instead carves a fixed number of slots from one aligned
// allocation — one iovec for io_uring_register_buffers — and acquire() returns an empty
// RecordBuffer (capacity 0) when every slot is out.
class BufferPool : public std::enable_shared_from_this<BufferPool> {
 public:
  BufferPool(std::size_t buffer_bytes, std::size_t max_free) : bytes_(buffer_bytes), max_free_(max_free) {}
  static std::shared_ptr<BufferPool> arena(std::size_t buffer_bytes, std::size_t slots);
  RecordBuffer acquire();
  void release(AlignedBuffer&& b);
  void release_slot(std::uint8_t* slot);
  std::uint8_t* arena_data() { return arena_.data(); }
  std::size_t arena_bytes() const { return arena_.size(); }
  // Allocates `count` buffers (AlignedBuffer writes every page) into the free list, raising
  // max_free to hold them: reads then land in memory already mapped (a first touch costs ~13 µs a
  // page on a paravirtualised VM; docs/real-engine.md §7a).
  void reserve(std::size_t count);
  std::size_t free_buffers() const;
  std::size_t buffer_bytes() const { return bytes_; }

 private:
  std::size_t bytes_, max_free_;
  mutable std::mutex m_;
  std::vector<AlignedBuffer> free_;  // guarded by m_
  AlignedBuffer arena_;              // arena pools: every slot; fixed after construction
  std::vector<std::uint8_t*> free_slots_;  // guarded by m_
};

// Why io_uring cannot be used here, or empty: io_uring_queue_init of a small ring (the test hook
// `fail_errno` or the environment variable VTSIM_TEST_IO_URING_ERRNO = ENOSYS | EPERM makes it
// fail as a kernel without io_uring or a seccomp filter would). For tools and tests.
std::string io_uring_unavailable(int fail_errno = 0);

// True when a read of `bytes` at `offset` into `buf` meets O_DIRECT's rules (4 KiB multiples).
bool direct_io_aligned(const void* buf, std::uint64_t offset, std::size_t bytes);

struct IoPoolConfig {
  int threads = 4;     // workers (config io.threads); psync: = reads in flight at once
  bool direct = true;  // O_DIRECT reads (config io.direct); false = through the page cache
  bool verify = true;  // check each record's checksum on the IO worker; false when the decode stage does
  std::size_t buffers = 0;  // record buffers made before the first read (at most IoPool::kKeptBuffers): the jobs in flight
  bool warm = false;        // each worker reads a record once before the constructor returns (warm_read)
  IoEngine engine = IoEngine::psync;  // config io.engine
  int queue_depth = 16;     // io_uring: reads in flight per worker (config io.queue_depth, 1..1024)
  // Test hook: io_uring_queue_init fails with this errno (ENOSYS: no io_uring; EPERM: seccomp)
  // so the psync fallback can be tested; 0 = as the kernel says (or VTSIM_TEST_IO_URING_ERRNO).
  int fail_ring_errno = 0;
};
// The queue depth checked: InputError naming io.queue_depth outside 1..1024.
int checked_queue_depth(int depth);

struct ReadRequest {
  RequestId id = 0;
  TileKey key;
  std::uint64_t priority = 0;  // lower first; ties in submission order
};

struct ReadResult {
  RequestId id = 0;
  TileKey key;
  std::uint64_t priority = 0;
  Fault fault = Fault::none;    // none, io_error, short_read (truncated file), checksum, bad_record (not in the store)
  std::string error;            // what went wrong, naming the file and the tile
  RecordBuffer record;          // the bytes read (aligned); the payload is the first stored_bytes
  std::uint32_t stored_bytes = 0;
  std::uint64_t bytes_read = 0;  // what pread returned (0 when the read failed or never started)
  Ticks read_start = 0, read_end = 0;
};

class IoPool {
 public:
  enum class State : std::uint8_t { running, stopping, stopped };
  using Sink = std::function<void(ReadResult&&)>;

  IoPool(const TileStore& store, const IoPoolConfig& cfg, const WallClock& clock, Sink sink,
         FaultLayer* faults = nullptr);
  ~IoPool();
  IoPool(const IoPool&) = delete;
  IoPool& operator=(const IoPool&) = delete;

  // false when the pool is stopping (the request is not taken) or the id is already queued.
  bool submit(const ReadRequest& r);
  // true: the request was still queued and is dropped (no read, no result).
  bool cancel(RequestId id);
  // Stops (idempotent): returns the requests that were queued and will never be read; waits for
  // reads under way (their results go to the sink) and joins the workers.
  std::vector<ReadRequest> stop();

  bool direct() const { return file_.direct(); }
  const std::string& warning() const { return warning_; }  // why O_DIRECT is off, or empty
  IoEngine engine() const { return engine_; }  // the engine that reads (psync after a fallback)
  int queue_depth() const { return engine_ == IoEngine::io_uring ? depth_ : 1; }  // reads in flight per worker
  // Why the io_uring engine was not used (psync reads instead), or why it runs without registered
  // buffers; empty when the engine asked for runs as designed.
  const std::string& engine_warning() const { return engine_warning_; }
  std::size_t queued() const { return queue_.size(); }
  int active() const { return active_.load(std::memory_order_relaxed); }
  int threads() const { return static_cast<int>(workers_.size()); }
  State state() const { return state_.load(std::memory_order_acquire); }
  std::size_t max_read_bytes() const { return buffers_->buffer_bytes(); }
  std::size_t free_buffers() const;  // record buffers ready for a read (the io_uring workers' arenas included)
  int warmed() const { return warm_done_.load(std::memory_order_acquire); }  // workers whose warm_read succeeded
  // Record buffers kept for reuse, and the most reserved up front (a record is ~50 KB at most).
  static constexpr std::size_t kKeptBuffers = 256;

  // One read as a worker performs it (also used by benchmarks and calibration): the record of
  // `key` into a buffer from `buffers`, with `plan`'s faults, checksum verified if `verify`.
  // Never throws. = prepare_read, pread_full, finish_read.
  static ReadResult read_record(const TileStore& store, const ReadFile& file, BufferPool& buffers, TileKey key,
                                const FaultPlan& plan, const WallClock& clock, bool verify = true);

  // The two halves of a read around the transfer, shared by both engines. prepare_read: the
  // record's location, a buffer (from `buffers`, or `preset` when it holds one), the injected short
  // read (half the record) and EIO (no read); it returns the bytes to read, or 0 when `r` already
  // failed. finish_read: the bytes that arrived (`error` = the errno of a failed read, 0 if none)
  // become r.bytes_read, a short read, an injected corruption, a checksum failure.
  struct Prepared {
    std::size_t ask = 0;    // bytes to read at `offset` (0: r already failed)
    std::uint64_t offset = 0;
  };
  static Prepared prepare_read(const TileStore& store, const ReadFile& file, BufferPool& buffers, TileKey key,
                               const FaultPlan& plan, const WallClock& clock, ReadResult& r, RecordBuffer preset = {});
  static void finish_read(const TileStore& store, const ReadFile& file, const FaultPlan& plan, const WallClock& clock,
                          bool verify, std::uint64_t offset, std::size_t bytes_read, int error, ReadResult& r);

 private:
  struct Ring;
  struct RingDeleter {
    void operator()(Ring* r) const;  // io_pool.cpp, where Ring is complete
  };
  void worker();
  void ring_worker(Ring& ring);
  void ring_warm(Ring& ring, int fd);  // the ring worker's warm_read
  void wake_one();   // io_uring: wakes a worker sleeping with room for a read
  void wake_all();
  // A worker's first read pays once for what later reads do not (the thread's first touches of its
  // stack and of the kernel's and libc's per-thread state): 0.3-1.6 ms on this project's VM against
  // ~0.1 ms warm (docs/real-engine.md §7a). Reads the coarsest tile of layer 0; no fault, no sink,
  // no result. With io.direct = false that one tile is then in the page cache. true: read whole.
  bool warm_read();

  const TileStore& store_;
  const WallClock& clock_;
  Sink sink_;
  FaultLayer* faults_;
  const bool verify_;
  const bool warm_;
  std::latch warmed_;  // counts the workers still warming
  std::atomic<int> warm_done_{0};
  ReadFile file_;
  std::string warning_;
  IoEngine engine_ = IoEngine::psync;
  int depth_ = 1;
  std::string engine_warning_;
  std::vector<std::unique_ptr<Ring, RingDeleter>> rings_;  // io_uring: one per worker, made before the workers
  std::shared_ptr<BufferPool> buffers_;
  WorkQueue<ReadRequest> queue_;
  std::atomic<int> active_{0};
  std::atomic<State> state_{State::running};
  std::mutex stop_m_;  // serialises stop()
  std::vector<std::thread> workers_;
};

}  // namespace vtsim
