#include "stream/exec/io_pool.h"

#include <algorithm>
#include <system_error>

#include "core/error.h"

namespace vtsim {

RecordBuffer::~RecordBuffer() {
  if (owner_ && buf_.size()) owner_->release(std::move(buf_));
}

RecordBuffer& RecordBuffer::operator=(RecordBuffer&& o) noexcept {
  if (this != &o) {
    if (owner_ && buf_.size()) owner_->release(std::move(buf_));
    buf_ = std::move(o.buf_);
    owner_ = std::move(o.owner_);
  }
  return *this;
}

RecordBuffer BufferPool::acquire() {
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
  return free_.size();
}

bool direct_io_aligned(const void* buf, std::uint64_t offset, std::size_t bytes) {
  constexpr std::uint64_t a = AlignedBuffer::kAlignment;
  return reinterpret_cast<std::uintptr_t>(buf) % a == 0 && offset % a == 0 && bytes % a == 0;
}

namespace {

std::size_t largest_read(const TileStore& store) {
  std::uint64_t m = store::kAlign;
  for (const auto& e : store.index()) m = std::max(m, store::round_up(e.stored_bytes, store::kAlign));
  return static_cast<std::size_t>(m);
}

}  // namespace

IoPool::IoPool(const TileStore& store, const IoPoolConfig& cfg, const WallClock& clock, Sink sink, FaultLayer* faults)
    : store_(store), clock_(clock), sink_(std::move(sink)), faults_(faults), verify_(cfg.verify), warm_(cfg.warm),
      warmed_(checked_workers(cfg.threads, "io.threads") * cfg.warm) {  // the workers to wait for: none unless warm
  DirectOpen o = open_for_read(store.path(), cfg.direct);
  file_ = std::move(o.file);
  warning_ = std::move(o.warning);
  if (file_.size() != store.header().file_bytes)
    throw InputError(store.path(), "the file changed since the store was opened (" + std::to_string(file_.size()) +
                                       " bytes, the header says " + std::to_string(store.header().file_bytes) + ")");
  buffers_ = std::make_shared<BufferPool>(largest_read(store), kKeptBuffers);
  buffers_->reserve(std::min(cfg.buffers, kKeptBuffers));
  start_workers(workers_, cfg.threads, queue_, [this] { worker(); });
  warmed_.wait();
}

IoPool::~IoPool() { stop(); }

bool IoPool::submit(const ReadRequest& r) {
  if (state() != State::running) return false;
  ReadRequest copy = r;
  return queue_.push(r.id, r.priority, std::move(copy));
}

bool IoPool::cancel(RequestId id) { return queue_.remove(id).has_value(); }

std::vector<ReadRequest> IoPool::stop() {
  std::lock_guard lock(stop_m_);
  std::vector<ReadRequest> dropped;
  if (state() == State::stopped) return dropped;
  state_.store(State::stopping, std::memory_order_release);
  for (auto& item : queue_.close()) dropped.push_back(std::move(item.task));
  for (auto& t : workers_)
    if (t.joinable()) t.join();
  state_.store(State::stopped, std::memory_order_release);
  return dropped;
}

ReadResult IoPool::read_record(const TileStore& store, const ReadFile& file, BufferPool& buffers, TileKey key,
                               const FaultPlan& plan, const WallClock& clock, bool verify) {
  ReadResult r;
  r.key = key;
  r.read_start = clock.now();
  if (!store.contains(key)) {
    r.fault = Fault::bad_record;
    r.error = store.path() + ": " + store::describe(key) + ": is outside the store";
    r.read_end = r.read_start;
    return r;
  }
  const TileLocation loc = store.locate(key);
  r.stored_bytes = loc.stored_bytes;
  try {
    r.record = buffers.acquire();
  } catch (const std::exception& e) {
    r.fault = Fault::io_error;
    r.error = store.path() + ": " + store::describe(key) + ": no memory for the read buffer (" + e.what() + ")";
    r.read_end = clock.now();
    return r;
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
    return r;
  }
  if (plan.fault == Fault::io_error) {
    r.fault = Fault::io_error;
    r.error = store.path() + ": " + store::describe(key) + ": read failed: Input/output error (injected)";
    r.read_end = clock.now();
    return r;
  }
  try {
    r.bytes_read = file.pread_full(r.record.data(), ask, loc.offset);
  } catch (const std::system_error& e) {
    r.fault = Fault::io_error;
    r.error = store.path() + ": " + store::describe(key) + ": " + e.what();
    r.read_end = clock.now();
    return r;
  }
  r.read_end = clock.now();
  if (r.bytes_read < loc.stored_bytes) {
    r.fault = Fault::short_read;
    r.error = store.path() + ": " + store::describe(key) + ": short read: " + std::to_string(r.bytes_read) + " of " +
              std::to_string(loc.stored_bytes) + " bytes at offset " + std::to_string(loc.offset) +
              (plan.fault == Fault::short_read ? " (injected)" : " (file truncated?)");
    return r;
  }
  if (plan.fault == Fault::checksum) r.record.data()[loc.stored_bytes / 2] ^= 0x5A;  // caught just below
  if (verify && store::checksum64(r.record.data(), loc.stored_bytes) != loc.checksum) {
    r.fault = Fault::checksum;
    r.error = store.path() + ": " + store::describe(key) + ": checksum mismatch: the record is corrupt" +
              (plan.fault == Fault::checksum ? " (injected)" : "");
  }
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

}  // namespace vtsim
