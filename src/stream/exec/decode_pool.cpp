#include "stream/exec/decode_pool.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>

#include "core/error.h"
#include "stream/store/i_codec.h"

namespace vtsim {

TileBufferPool::SizeClass& TileBufferPool::size_class(std::size_t bytes) {
  for (SizeClass& c : classes_)
    if (c.bytes == bytes) return c;
  classes_.push_back(SizeClass{bytes, max_free_, {}});
  return classes_.back();
}

std::unique_ptr<std::uint8_t[]> TileBufferPool::acquire(std::size_t bytes) {
  {
    std::lock_guard lock(m_);
    SizeClass& c = size_class(bytes);
    if (!c.free.empty()) {
      auto b = std::move(c.free.back());
      c.free.pop_back();
      return b;
    }
  }
  return std::make_unique_for_overwrite<std::uint8_t[]>(bytes);
}

void TileBufferPool::release(std::unique_ptr<std::uint8_t[]> buf, std::size_t bytes) {
  std::lock_guard lock(m_);
  SizeClass& c = size_class(bytes);
  if (c.free.size() < c.max_free) c.free.push_back(std::move(buf));
}

void TileBufferPool::reserve(std::size_t bytes, std::size_t count) {
  std::vector<std::unique_ptr<std::uint8_t[]>> made;
  made.reserve(count);
  const long page = sysconf(_SC_PAGESIZE);
  for (std::size_t i = 0; i < count; ++i) {
    made.push_back(std::make_unique_for_overwrite<std::uint8_t[]>(bytes));
    // Map the pages in one call (Linux 5.14+; ignored where unsupported), then write each once: on
    // this project's VM, a paravirtualised guest, the first write to a mapped page still traps.
    // 113 MB this way took 0.22 s, against 0.38 s by writes alone, and the decodes' own writes
    // afterwards 6 ms, against 170 ms after the mapping alone (docs/real-engine.md §7a).
    const auto a = reinterpret_cast<std::uintptr_t>(made.back().get());
    const std::uintptr_t lo = a / static_cast<std::uintptr_t>(page) * static_cast<std::uintptr_t>(page);
    madvise(reinterpret_cast<void*>(lo), a + bytes - lo, MADV_POPULATE_WRITE);
    for (std::size_t o = 0; o < bytes; o += static_cast<std::size_t>(page)) made.back()[o] = 0;
  }
  std::lock_guard lock(m_);
  SizeClass& c = size_class(bytes);
  c.max_free = std::max(c.max_free, c.free.size() + count);
  for (auto& b : made) c.free.push_back(std::move(b));
}

std::size_t TileBufferPool::free_buffers(std::size_t bytes) const {
  std::lock_guard lock(m_);
  for (const SizeClass& c : classes_)
    if (c.bytes == bytes) return c.free.size();
  return 0;
}

DecodeResult decode_record(const TileStore& store, TileKey key, const std::uint8_t* record, std::size_t size, bool verify,
                           const std::shared_ptr<TileBufferPool>& buffers) {
  DecodeResult r;
  r.key = key;
  // The tile named for error messages only: a successful decode formats no string.
  const auto where = [&] { return store.path() + ": " + store::describe(key); };
  if (!store.contains(key)) {
    r.fault = Fault::bad_record;
    r.error = where() + ": is outside the store";
    return r;
  }
  const store::IndexEntry& e = store.index()[store.geometry().slot(key)];
  if (size < e.stored_bytes) {
    r.fault = Fault::bad_record;
    r.error = where() + ": record has " + std::to_string(size) + " bytes, the index says " + std::to_string(e.stored_bytes);
    return r;
  }
  if (verify && store::checksum64(record, e.stored_bytes) != e.checksum) {
    r.fault = Fault::checksum;
    r.error = where() + ": checksum mismatch: the record is corrupt";
    return r;
  }
  try {
    std::shared_ptr<TileData> t;
    if (buffers) {
      t = std::shared_ptr<TileData>(new TileData, [buffers](TileData* p) {
        if (p->texels) buffers->release(std::move(p->texels), p->bytes);
        delete p;
      });
      t->texels = buffers->acquire(e.decoded_bytes);
    } else {
      t = std::make_shared<TileData>();
      t->texels = std::make_unique_for_overwrite<std::uint8_t[]>(e.decoded_bytes);
    }
    t->key = key;
    t->side = store.geometry().stored_side();
    t->channels = store.layer(key.layer()).channels;
    t->bytes = e.decoded_bytes;
    decoder_for(e.codec).decode(record, e.stored_bytes, static_cast<int>(t->side), static_cast<int>(t->side),
                                static_cast<int>(t->channels), t->texels.get());
    r.data = std::move(t);
  } catch (const CodecError& err) {
    r.fault = Fault::decode_error;
    r.error = where() + ": does not decode: " + err.what();
  } catch (const std::exception& err) {
    r.fault = Fault::decode_error;
    r.error = where() + ": decode failed: " + err.what();
  }
  return r;
}

DecodePool::DecodePool(const TileStore& store, int workers, const WallClock& clock, Sink sink, bool verify, bool warm)
    : store_(store), clock_(clock), sink_(std::move(sink)), verify_(verify), warm_(warm),
      warmed_(checked_workers(workers, "decode.workers") * warm) {  // the workers to wait for: none unless warm
  start_workers(workers_, workers, queue_, [this] { worker(); });
  warmed_.wait();
}

DecodePool::~DecodePool() { stop(); }

bool DecodePool::submit(DecodeTask& task) {
  if (state() != State::running) return false;
  const RequestId id = task.id;
  const std::uint64_t prio = task.priority;
  DecodeTask moved = std::move(task);
  if (queue_.push(id, prio, std::move(moved))) return true;
  task = std::move(moved);  // push refused: it did not take the task
  return false;
}

bool DecodePool::cancel(RequestId id) { return queue_.remove(id).has_value(); }

std::vector<RequestId> DecodePool::stop() {
  std::lock_guard lock(stop_m_);
  std::vector<RequestId> dropped;
  if (state() == State::stopped) return dropped;
  state_.store(State::stopping, std::memory_order_release);
  for (auto& item : queue_.close()) dropped.push_back(item.id);
  for (auto& t : workers_)
    if (t.joinable()) t.join();
  state_.store(State::stopped, std::memory_order_release);
  return dropped;
}

bool DecodePool::warm_decode() {
  bool ok = true;
  try {
    AlignedBuffer scratch;
    for (std::uint32_t layer = 0; layer < store_.layer_count(); ++layer) {
      const std::size_t bytes = store_.tile_bytes(layer);
      auto out = tiles_->acquire(bytes);
      try {
        store_.read_tile(TileKey(layer, store_.geometry().levels - 1, 0, 0), scratch, out.get(), bytes);
      } catch (const std::exception&) {
        ok = false;
      }
      tiles_->release(std::move(out), bytes);
    }
  } catch (...) {  // no memory for a buffer
    return false;
  }
  return ok;
}

void DecodePool::worker() {
  if (warm_) {
    if (warm_decode()) warm_done_.fetch_add(1, std::memory_order_release);
    warmed_.count_down();
  }
  while (auto item = queue_.pop_wait()) {
    active_.fetch_add(1, std::memory_order_relaxed);
    DecodeTask& t = item->task;
    const Ticks start = clock_.now();
    DecodeResult r = decode_record(store_, t.key, t.record.data(), t.size, verify_, tiles_);
    r.id = t.id;
    r.decode_start = start;
    r.decode_end = clock_.now();
    t.record = RecordBuffer();  // back to the IO pool's buffers before the result travels on
    sink_(std::move(r));
    active_.fetch_sub(1, std::memory_order_relaxed);
  }
}

}  // namespace vtsim
