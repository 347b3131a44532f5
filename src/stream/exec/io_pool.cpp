#include "stream/exec/io_pool.h"

#include <liburing.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <system_error>

#include "core/error.h"

namespace vtsim {

void RecordBuffer::give_back() {
  if (!owner_) return;
  if (slot_) owner_->release_slot(std::exchange(slot_, nullptr));
  else if (buf_.size()) owner_->release(std::move(buf_));
}

RecordBuffer::~RecordBuffer() { give_back(); }

RecordBuffer::RecordBuffer(RecordBuffer&& o) noexcept
    : buf_(std::move(o.buf_)), slot_(std::exchange(o.slot_, nullptr)), owner_(std::move(o.owner_)) {}

RecordBuffer& RecordBuffer::operator=(RecordBuffer&& o) noexcept {
  if (this != &o) {
    give_back();
    buf_ = std::move(o.buf_);
    slot_ = std::exchange(o.slot_, nullptr);
    owner_ = std::move(o.owner_);
  }
  return *this;
}

std::size_t RecordBuffer::capacity() const { return slot_ ? owner_->buffer_bytes() : buf_.size(); }

std::shared_ptr<BufferPool> BufferPool::arena(std::size_t buffer_bytes, std::size_t slots) {
  auto p = std::make_shared<BufferPool>(buffer_bytes, 0);
  p->arena_ = AlignedBuffer(buffer_bytes * slots);  // buffer_bytes is a multiple of 4096
  p->free_slots_.reserve(slots);
  for (std::size_t i = slots; i-- > 0;) p->free_slots_.push_back(p->arena_.data() + i * buffer_bytes);
  return p;
}

void BufferPool::release_slot(std::uint8_t* slot) {
  std::lock_guard lock(m_);
  free_slots_.push_back(slot);
}

RecordBuffer BufferPool::acquire() {
  if (arena_.size()) {
    std::lock_guard lock(m_);
    if (free_slots_.empty()) return {};
    std::uint8_t* s = free_slots_.back();
    free_slots_.pop_back();
    return RecordBuffer(s, shared_from_this());
  }
  {
    std::lock_guard lock(m_);
    if (!free_.empty()) {
      AlignedBuffer b = std::move(free_.back());
      free_.pop_back();
      return RecordBuffer(std::move(b), shared_from_this());
    }
  }
  return RecordBuffer(AlignedBuffer(bytes_), shared_from_this());
}

void BufferPool::release(AlignedBuffer&& b) {
  std::lock_guard lock(m_);
  if (free_.size() < max_free_) free_.push_back(std::move(b));
}

void BufferPool::reserve(std::size_t count) {
  std::vector<AlignedBuffer> made;
  made.reserve(count);
  for (std::size_t i = 0; i < count; ++i) made.emplace_back(bytes_);
  std::lock_guard lock(m_);
  max_free_ = std::max(max_free_, free_.size() + count);
  for (AlignedBuffer& b : made) free_.push_back(std::move(b));
}

std::size_t BufferPool::free_buffers() const {
  std::lock_guard lock(m_);
  return free_.size() + free_slots_.size();
}

bool direct_io_aligned(const void* buf, std::uint64_t offset, std::size_t bytes) {
  constexpr std::uint64_t a = AlignedBuffer::kAlignment;
  return reinterpret_cast<std::uintptr_t>(buf) % a == 0 && offset % a == 0 && bytes % a == 0;
}

const Registry<IoEngineInfo>& io_engines() {
  static const Registry<IoEngineInfo> engines(
      "IO engine",
      {
          {"psync", "one pread in flight per IO thread (as fio's psync engine)", IoEngine::psync},
          {"io_uring", "each IO thread keeps io.queue_depth reads in flight on its own io_uring (registered buffers and file)",
           IoEngine::io_uring},
      });
  return engines;
}

std::string_view engine_name(IoEngine e) {
  for (const IoEngineInfo& i : io_engines().entries())
    if (i.engine == e) return i.name;
  return "?";
}

int checked_queue_depth(int depth) {
  if (depth < 1 || depth > 1024) throw InputError("io.queue_depth", "must be in 1..1024, got " + std::to_string(depth));
  return depth;
}

namespace {

std::size_t largest_read(const TileStore& store) {
  std::uint64_t m = store::kAlign;
  for (const auto& e : store.index()) m = std::max(m, store::round_up(e.stored_bytes, store::kAlign));
  return static_cast<std::size_t>(m);
}

// The errno io_uring_queue_init is made to fail with: the hook, else VTSIM_TEST_IO_URING_ERRNO
// (ENOSYS or EPERM; any other non-empty value counts as ENOSYS), else 0.
int forced_ring_errno(int hook) {
  if (hook != 0) return hook;
  const char* env = std::getenv("VTSIM_TEST_IO_URING_ERRNO");
  if (!env || !*env) return 0;
  return std::strcmp(env, "EPERM") == 0 ? EPERM : ENOSYS;
}

// Why io_uring_queue_init failed, and what the pool does instead.
std::string ring_failure(int err) {
  std::string why = std::strerror(err);
  if (err == ENOSYS) why += " (ENOSYS: this kernel has no io_uring)";
  else if (err == EPERM || err == EACCES) why += " (a seccomp filter or kernel.io_uring_disabled refuses io_uring)";
  else if (err == ENOMEM) why += " (ENOMEM: no memory for the ring, or RLIMIT_MEMLOCK too low)";
  return "io.engine = io_uring: io_uring_queue_init failed: " + why +
         "; reading with psync instead (one read in flight per IO thread)";
}

// user_data tags of a ring's completions: reads are slot + 1, timeouts (injected slow reads)
// slot | kTimeoutTag.
constexpr std::uint64_t kWakeTag = ~std::uint64_t{0};
constexpr std::uint64_t kRemoveTag = ~std::uint64_t{0} - 1;
constexpr std::uint64_t kWarmTag = ~std::uint64_t{0} - 2;
constexpr std::uint64_t kTimeoutTag = std::uint64_t{1} << 62;

// A ring's read slot: free, waiting out an injected delay (a timeout in the ring), or reading.
enum class RingPhase : std::uint8_t { free, delay, read };
struct RingSlot {
  ReadRequest q;
  FaultPlan plan;
  ReadResult r;
  Ticks start = 0;
  std::uint64_t offset = 0;
  std::size_t ask = 0, done = 0;
  RingPhase phase = RingPhase::free;
  __kernel_timespec ts{};
};

// A submission entry, after a submit to make room if the ring is full; null if there is still none.
io_uring_sqe* ring_sqe(io_uring* ring) {
  io_uring_sqe* e = io_uring_get_sqe(ring);
  if (!e) {
    io_uring_submit(ring);
    e = io_uring_get_sqe(ring);
  }
  return e;
}

}  // namespace

std::string io_uring_unavailable(int fail_errno) {
  if (const int e = forced_ring_errno(fail_errno)) return ring_failure(e);
  io_uring ring{};
  const int rc = io_uring_queue_init(4, &ring, 0);
  if (rc < 0) return ring_failure(-rc);
  io_uring_queue_exit(&ring);
  return {};
}

// One worker's io_uring: the ring, its wake-up eventfd, its registered buffer arena. Made on the
// constructor's thread before the worker starts; afterwards only `sleep` is shared.
struct IoPool::Ring {
  enum class Sleep : std::uint8_t { busy, idle };  // idle: waiting in the ring with room for a read
  io_uring ring{};
  int ring_rc = -1;          // io_uring_queue_init's result (0: the ring exists)
  int wake_fd = -1;          // eventfd: submit and stop write it, a read of it sits in the ring
  std::uint64_t wake_value = 0;  // the eventfd read's target (the worker's own)
  std::shared_ptr<BufferPool> arena;  // the record buffers of this worker's reads
  int buffers_registered = 0;  // 1: arena registered (IORING_OP_READ_FIXED), 0: plain reads
  int file_registered = 0;     // 1: the store's descriptor is fixed file 0
  std::atomic<Sleep> sleep{Sleep::busy};

  Ring() = default;
  Ring(const Ring&) = delete;
  Ring& operator=(const Ring&) = delete;
  ~Ring() {
    if (ring_rc == 0) io_uring_queue_exit(&ring);
    if (wake_fd >= 0) ::close(wake_fd);
  }
};

void IoPool::RingDeleter::operator()(Ring* r) const { delete r; }

IoPool::IoPool(const TileStore& store, const IoPoolConfig& cfg, const WallClock& clock, Sink sink, FaultLayer* faults)
    : store_(store), clock_(clock), sink_(std::move(sink)), faults_(faults), verify_(cfg.verify), warm_(cfg.warm),
      warmed_(checked_workers(cfg.threads, "io.threads") * cfg.warm) {  // the workers to wait for: none unless warm
  if (cfg.engine == IoEngine::io_uring) depth_ = checked_queue_depth(cfg.queue_depth);
  DirectOpen o = open_for_read(store.path(), cfg.direct);
  file_ = std::move(o.file);
  warning_ = std::move(o.warning);
  if (file_.size() != store.header().file_bytes)
    throw InputError(store.path(), "the file changed since the store was opened (" + std::to_string(file_.size()) +
                                       " bytes, the header says " + std::to_string(store.header().file_bytes) + ")");
  buffers_ = std::make_shared<BufferPool>(largest_read(store), kKeptBuffers);
  if (cfg.engine == IoEngine::io_uring) {
    engine_ = IoEngine::io_uring;
    // Each worker's arena: its reads in flight and its share of the records waiting for decode
    // (cfg.buffers); beyond that a read takes a heap buffer from buffers_ (a plain, unregistered read).
    const std::size_t per_worker = std::min<std::size_t>(
        1024, static_cast<std::size_t>(depth_) + (cfg.buffers + static_cast<std::size_t>(cfg.threads) - 1) / static_cast<std::size_t>(cfg.threads));
    const int forced = forced_ring_errno(cfg.fail_ring_errno);
    std::string unregistered;
    for (int i = 0; i < cfg.threads; ++i) {
      std::unique_ptr<Ring, RingDeleter> g(new Ring);
      // SQ room for every slot's read and timeout-remove, plus the eventfd read.
      g->ring_rc = forced ? -forced : io_uring_queue_init(static_cast<unsigned>(2 * depth_ + 2), &g->ring, 0);
      if (g->ring_rc < 0) {
        engine_warning_ = ring_failure(-g->ring_rc);
        break;
      }
      g->wake_fd = ::eventfd(0, EFD_CLOEXEC);
      if (g->wake_fd < 0) {
        engine_warning_ = std::string("io.engine = io_uring: eventfd failed: ") + std::strerror(errno) + "; reading with psync instead";
        rings_.push_back(std::move(g));  // closed below
        break;
      }
      g->arena = BufferPool::arena(buffers_->buffer_bytes(), per_worker);
      const iovec iov{g->arena->arena_data(), g->arena->arena_bytes()};
      if (const int rc = io_uring_register_buffers(&g->ring, &iov, 1); rc == 0) g->buffers_registered = 1;
      else unregistered = std::strerror(-rc);
      const int fd = file_.fd();
      g->file_registered = io_uring_register_files(&g->ring, &fd, 1) == 0 ? 1 : 0;
      rings_.push_back(std::move(g));
    }
    if (!engine_warning_.empty()) {
      rings_.clear();
      engine_ = IoEngine::psync;
    } else if (!unregistered.empty()) {
      engine_warning_ = "io.engine = io_uring: io_uring_register_buffers failed (" + unregistered +
                        "; RLIMIT_MEMLOCK?): reads go to unregistered buffers";
    }
  }
  if (engine_ == IoEngine::psync) {
    buffers_->reserve(std::min(cfg.buffers, kKeptBuffers));
    start_workers(workers_, cfg.threads, queue_, [this] { worker(); });
  } else {
    workers_.reserve(rings_.size());
    try {
      for (auto& g : rings_) workers_.emplace_back([this, r = g.get()] { ring_worker(*r); });
    } catch (...) {
      queue_.close();
      wake_all();
      for (std::thread& t : workers_) t.join();
      workers_.clear();
      throw;
    }
  }
  warmed_.wait();
}

IoPool::~IoPool() { stop(); }

std::size_t IoPool::free_buffers() const {
  std::size_t n = buffers_->free_buffers();
  for (const auto& g : rings_) n += g->arena->free_buffers();
  return n;
}

bool IoPool::submit(const ReadRequest& r) {
  if (state() != State::running) return false;
  ReadRequest copy = r;
  if (!queue_.push(r.id, r.priority, std::move(copy))) return false;
  if (engine_ == IoEngine::io_uring) wake_one();
  return true;
}

void IoPool::wake_one() {
  for (auto& g : rings_) {
    auto expected = Ring::Sleep::idle;
    if (g->sleep.compare_exchange_strong(expected, Ring::Sleep::busy)) {
      ::eventfd_write(g->wake_fd, 1);
      return;
    }
  }
}

void IoPool::wake_all() {
  for (auto& g : rings_)
    if (g->wake_fd >= 0) ::eventfd_write(g->wake_fd, 1);
}

bool IoPool::cancel(RequestId id) { return queue_.remove(id).has_value(); }

std::vector<ReadRequest> IoPool::stop() {
  std::lock_guard lock(stop_m_);
  std::vector<ReadRequest> dropped;
  if (state() == State::stopped) return dropped;
  state_.store(State::stopping, std::memory_order_release);
  for (auto& item : queue_.close()) dropped.push_back(std::move(item.task));
  wake_all();
  for (auto& t : workers_)
    if (t.joinable()) t.join();
  state_.store(State::stopped, std::memory_order_release);
  return dropped;
}

IoPool::Prepared IoPool::prepare_read(const TileStore& store, const ReadFile& file, BufferPool& buffers, TileKey key,
                                      const FaultPlan& plan, const WallClock& clock, ReadResult& r, RecordBuffer preset) {
  r.key = key;
  r.read_start = clock.now();
  if (!store.contains(key)) {
    r.fault = Fault::bad_record;
    r.error = store.path() + ": " + store::describe(key) + ": is outside the store";
    r.read_end = r.read_start;
    return {};
  }
  const TileLocation loc = store.locate(key);
  r.stored_bytes = loc.stored_bytes;
  try {
    r.record = preset.capacity() ? std::move(preset) : buffers.acquire();
  } catch (const std::exception& e) {
    r.fault = Fault::io_error;
    r.error = store.path() + ": " + store::describe(key) + ": no memory for the read buffer (" + e.what() + ")";
    r.read_end = clock.now();
    return {};
  }
  // An injected short read asks for half the record (rounded down to the O_DIRECT unit), as if
  // the file ended there.
  std::size_t ask = loc.read_bytes;
  if (plan.fault == Fault::short_read) ask = ask / 2 / store::kAlign * store::kAlign;
  if (ask > r.record.capacity() || (file.direct() && !direct_io_aligned(r.record.data(), loc.offset, ask))) {
    r.fault = Fault::bad_record;
    r.error = store.path() + ": " + store::describe(key) + ": record at " + std::to_string(loc.offset) + " (" +
              std::to_string(ask) + " bytes) is not an aligned read";
    r.read_end = clock.now();
    return {};
  }
  if (plan.fault == Fault::io_error) {
    r.fault = Fault::io_error;
    r.error = store.path() + ": " + store::describe(key) + ": read failed: Input/output error (injected)";
    r.read_end = clock.now();
    return {};
  }
  if (ask == 0) {  // an injected short read of a one-block record: nothing to ask for
    finish_read(store, file, plan, clock, false, loc.offset, 0, 0, r);
    return {};
  }
  return {ask, loc.offset};
}

void IoPool::finish_read(const TileStore& store, const ReadFile& file, const FaultPlan& plan, const WallClock& clock,
                         bool verify, std::uint64_t offset, std::size_t bytes_read, int error, ReadResult& r) {
  r.read_end = clock.now();
  r.bytes_read = bytes_read;
  if (error != 0) {
    r.fault = Fault::io_error;
    r.bytes_read = 0;
    r.error = store.path() + ": " + store::describe(r.key) + ": " +
              std::system_error(error, std::generic_category(), "read " + file.path() + " at offset " + std::to_string(offset + bytes_read)).what();
    return;
  }
  const TileLocation loc = store.locate(r.key);
  if (r.bytes_read < loc.stored_bytes) {
    r.fault = Fault::short_read;
    r.error = store.path() + ": " + store::describe(r.key) + ": short read: " + std::to_string(r.bytes_read) + " of " +
              std::to_string(loc.stored_bytes) + " bytes at offset " + std::to_string(loc.offset) +
              (plan.fault == Fault::short_read ? " (injected)" : " (file truncated?)");
    return;
  }
  if (plan.fault == Fault::checksum) r.record.data()[loc.stored_bytes / 2] ^= 0x5A;  // caught just below
  if (verify && store::checksum64(r.record.data(), loc.stored_bytes) != loc.checksum) {
    r.fault = Fault::checksum;
    r.error = store.path() + ": " + store::describe(r.key) + ": checksum mismatch: the record is corrupt" +
              (plan.fault == Fault::checksum ? " (injected)" : "");
  }
}

ReadResult IoPool::read_record(const TileStore& store, const ReadFile& file, BufferPool& buffers, TileKey key,
                               const FaultPlan& plan, const WallClock& clock, bool verify) {
  ReadResult r;
  const Prepared p = prepare_read(store, file, buffers, key, plan, clock, r);
  if (p.ask == 0) return r;
  std::size_t got = 0;
  try {
    got = file.pread_full(r.record.data(), p.ask, p.offset);
  } catch (const std::system_error& e) {
    r.fault = Fault::io_error;
    r.error = store.path() + ": " + store::describe(key) + ": " + e.what();
    r.read_end = clock.now();
    return r;
  }
  finish_read(store, file, plan, clock, verify, p.offset, got, 0, r);
  return r;
}

bool IoPool::warm_read() {
  const TileKey k(0, store_.geometry().levels - 1, 0, 0);
  try {
    return read_record(store_, file_, *buffers_, k, FaultPlan{}, clock_, /*verify=*/false).fault == Fault::none;
  } catch (...) {  // no memory for the error text: the real request will say
    return false;
  }
}

void IoPool::worker() {
  if (warm_) {
    if (warm_read()) warm_done_.fetch_add(1, std::memory_order_release);
    warmed_.count_down();
  }
  while (auto item = queue_.pop_wait()) {
    active_.fetch_add(1, std::memory_order_relaxed);
    const ReadRequest& q = item->task;
    const FaultPlan plan = faults_ ? faults_->next(q.key) : FaultPlan{};
    const Ticks start = clock_.now();
    // A slow request: the device takes `delay` longer (part of the read's time); shutdown does
    // not wait for it.
    if (plan.delay > 0) queue_.sleep_unless_closed(std::chrono::nanoseconds(plan.delay));
    ReadResult r = read_record(store_, file_, *buffers_, q.key, plan, clock_, verify_);
    r.read_start = start;
    r.id = q.id;
    r.priority = q.priority;
    sink_(std::move(r));
    active_.fetch_sub(1, std::memory_order_relaxed);
  }
}

// The io_uring worker: up to depth_ slots, each a request from its pop to its delivery (an
// injected slow read first waits on an IORING_OP_TIMEOUT, then reads). A completion with fewer
// bytes than asked is read on from where it stopped (as pread_full does); 0 bytes is the end of
// the file; a negative result is the errno of a failed read. Everything the psync worker does to
// a read (fault plan, prepare_read, finish_read) is done here in the same order.
// A ring worker's first read (warm_read's, through the ring): the coarsest tile of layer 0.
void IoPool::ring_warm(Ring& g, int fd) {
  io_uring* ring = &g.ring;
  auto get_sqe = [ring] { return ring_sqe(ring); };
  int ok = 0;
  try {
    ReadResult r;
    const TileKey k(0, store_.geometry().levels - 1, 0, 0);
    const Prepared p = prepare_read(store_, file_, *buffers_, k, FaultPlan{}, clock_, r, g.arena->acquire());
    io_uring_sqe* e = p.ask ? get_sqe() : nullptr;
    if (e) {
      if (g.buffers_registered && r.record.in_arena()) io_uring_prep_read_fixed(e, fd, r.record.data(), static_cast<unsigned>(p.ask), p.offset, 0);
      else io_uring_prep_read(e, fd, r.record.data(), static_cast<unsigned>(p.ask), p.offset);
      if (g.file_registered) io_uring_sqe_set_flags(e, IOSQE_FIXED_FILE);
      io_uring_sqe_set_data64(e, kWarmTag);
      io_uring_cqe* cqe = nullptr;
      if (io_uring_submit_and_wait(ring, 1) >= 0 && io_uring_wait_cqe(ring, &cqe) == 0) {
        ok = cqe->res == static_cast<int>(p.ask);
        io_uring_cqe_seen(ring, cqe);
      }
    }
  } catch (...) {  // no memory for the error text: the real request will say
  }
  if (ok) warm_done_.fetch_add(1, std::memory_order_release);
  warmed_.count_down();
}

void IoPool::ring_worker(Ring& g) {
  io_uring* ring = &g.ring;
  const int fd = g.file_registered ? 0 : file_.fd();
  using Phase = RingPhase;
  using Slot = RingSlot;
  std::vector<Slot> slots(static_cast<std::size_t>(depth_));
  std::vector<std::size_t> free_slots;
  for (std::size_t i = slots.size(); i-- > 0;) free_slots.push_back(i);
  int in_flight = 0;

  auto get_sqe = [ring] { return ring_sqe(ring); };
  auto deliver = [&](std::size_t i) {
    Slot& s = slots[i];
    s.r.read_start = s.start;
    s.r.id = s.q.id;
    s.r.priority = s.q.priority;
    sink_(std::move(s.r));
    s.r = ReadResult{};
    s.phase = Phase::free;
    free_slots.push_back(i);
    --in_flight;
    active_.fetch_sub(1, std::memory_order_relaxed);
  };
  auto issue = [&](std::size_t i) {  // the (rest of the) slot's read
    Slot& s = slots[i];
    io_uring_sqe* e = get_sqe();
    if (!e) {  // no submission entry even after a submit: read synchronously, as psync would
      std::size_t got = s.done;
      int err = 0;
      try {
        got += file_.pread_full(s.r.record.data() + s.done, s.ask - s.done, s.offset + s.done);
      } catch (const std::system_error& x) {
        err = x.code().value();
      }
      finish_read(store_, file_, s.plan, clock_, verify_, s.offset, got, err, s.r);
      deliver(i);
      return;
    }
    std::uint8_t* dst = s.r.record.data() + s.done;
    const auto len = static_cast<unsigned>(s.ask - s.done);
    if (g.buffers_registered && s.r.record.in_arena()) io_uring_prep_read_fixed(e, fd, dst, len, s.offset + s.done, 0);
    else io_uring_prep_read(e, fd, dst, len, s.offset + s.done);
    if (g.file_registered) io_uring_sqe_set_flags(e, IOSQE_FIXED_FILE);
    io_uring_sqe_set_data64(e, i + 1);
    s.phase = Phase::read;
  };
  auto begin_read = [&](std::size_t i) {  // after the slot's delay, if any
    Slot& s = slots[i];
    RecordBuffer preset = g.arena->acquire();
    const Prepared p = prepare_read(store_, file_, *buffers_, s.q.key, s.plan, clock_, s.r, std::move(preset));
    if (p.ask == 0) return deliver(i);
    s.ask = p.ask;
    s.offset = p.offset;
    s.done = 0;
    issue(i);
  };
  auto start = [&](ReadRequest&& q) {
    const std::size_t i = free_slots.back();
    free_slots.pop_back();
    ++in_flight;
    active_.fetch_add(1, std::memory_order_relaxed);
    Slot& s = slots[i];
    s.q = std::move(q);
    s.plan = faults_ ? faults_->next(s.q.key) : FaultPlan{};
    s.start = clock_.now();
    if (s.plan.delay > 0) {  // a slow request: the device takes `delay` longer; stop removes the wait
      io_uring_sqe* e = get_sqe();
      if (e) {
        s.ts.tv_sec = s.plan.delay / 1'000'000'000;
        s.ts.tv_nsec = s.plan.delay % 1'000'000'000;
        io_uring_prep_timeout(e, &s.ts, 0, 0);
        io_uring_sqe_set_data64(e, kTimeoutTag | i);
        s.phase = Phase::delay;
        return;
      }
    }
    begin_read(i);
  };
  auto post_wake = [&] {
    if (io_uring_sqe* e = get_sqe()) {
      io_uring_prep_read(e, g.wake_fd, &g.wake_value, sizeof g.wake_value, 0);
      io_uring_sqe_set_data64(e, kWakeTag);
    }
  };
  auto handle = [&](std::uint64_t tag, int res) {
    if (tag == kWakeTag) return post_wake();
    if (tag == kRemoveTag || tag == kWarmTag) return;
    if (tag & kTimeoutTag) {
      const std::size_t i = static_cast<std::size_t>(tag & ~kTimeoutTag);
      if (i < slots.size() && slots[i].phase == Phase::delay) begin_read(i);
      return;
    }
    const std::size_t i = static_cast<std::size_t>(tag - 1);
    if (i >= slots.size() || slots[i].phase != Phase::read) return;
    Slot& s = slots[i];
    if (res == -EINTR || res == -EAGAIN) return issue(i);
    if (res < 0) {
      finish_read(store_, file_, s.plan, clock_, verify_, s.offset, s.done, -res, s.r);
      return deliver(i);
    }
    s.done += static_cast<std::size_t>(res);
    if (res > 0 && s.done < s.ask) return issue(i);  // read on from where it stopped
    finish_read(store_, file_, s.plan, clock_, verify_, s.offset, s.done, 0, s.r);
    deliver(i);
  };

  if (warm_) ring_warm(g, fd);  // one read through the ring, before the pool's constructor returns

  post_wake();
  std::vector<std::pair<std::uint64_t, int>> batch;  // a wake-up's completions (tag, res)
  batch.reserve(static_cast<std::size_t>(depth_) + 1);
  int removed = 0;  // the slow reads' timeouts were removed (once, at stop)
  for (;;) {
    while (in_flight < depth_) {
      auto item = queue_.try_pop();
      if (!item) break;
      start(std::move(item->task));
    }
    const bool closing = queue_.state() != WorkQueue<ReadRequest>::State::open;
    if (closing && !removed) {  // stop: a slow read's wait ends now, its read follows
      removed = 1;
      for (std::size_t i = 0; i < slots.size(); ++i)
        if (slots[i].phase == Phase::delay)
          if (io_uring_sqe* e = get_sqe()) {
            io_uring_prep_timeout_remove(e, kTimeoutTag | i, 0);
            io_uring_sqe_set_data64(e, kRemoveTag);
          }
    }
    if (closing && in_flight == 0) break;
    if (!closing && in_flight < depth_) {
      // Idle with room: say so, then look at the queue once more (a submit after this look sees
      // idle and writes the eventfd; one before it left a request this look finds).
      g.sleep.store(Ring::Sleep::idle, std::memory_order_seq_cst);
      if (queue_.size() > 0 || queue_.state() != WorkQueue<ReadRequest>::State::open) {
        g.sleep.store(Ring::Sleep::busy, std::memory_order_seq_cst);
        continue;
      }
    }
    // One system call submits what the slots prepared and waits for a completion (as fio does).
    const int rc = io_uring_submit_and_wait(ring, 1);
    g.sleep.store(Ring::Sleep::busy, std::memory_order_seq_cst);
    if (rc < 0 && rc != -EINTR && rc != -EAGAIN && rc != -EBUSY) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    io_uring_cqe* cqe = nullptr;
    batch.clear();  // every completion there is, then handled (handling submits more)
    while (io_uring_peek_cqe(ring, &cqe) == 0) {
      batch.emplace_back(cqe->user_data, cqe->res);
      io_uring_cqe_seen(ring, cqe);
    }
    for (const auto& [tag, res] : batch) handle(tag, res);
  }
}

}  // namespace vtsim
