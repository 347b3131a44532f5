#include "stream/exec/threaded_executor.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <thread>

#include <fmt/format.h>

namespace vtsim {

ThreadedExecutor::ThreadedExecutor(const TileStore& store, const ThreadedExecutorConfig& cfg)
    : faults_(cfg.faults), capacity_(cfg.capacity) {
  if (capacity_ == 0) throw std::invalid_argument("ThreadedExecutor: capacity must be positive");
  const int workers = cfg.decode_workers > 0 ? cfg.decode_workers : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  // Checksums are checked on the decode workers, not the IO workers (io_pool.h says why); a corrupt
  // record is then found after the decode queue, as the simulated clock models it.
  decode_ = std::make_unique<DecodePool>(
      store, workers, clock_, [this](DecodeResult&& r) { on_decoded(std::move(r)); }, /*verify=*/true, cfg.warm);
  if (const std::uint64_t count = reserved_pages(store, cfg); count > 0)
    for (std::uint32_t i = 0; i < store.layer_count(); ++i) decode_->reserve_tiles(store.tile_bytes(i), count);
  IoPoolConfig ic{cfg.io_threads, cfg.direct, /*verify=*/false, capacity_, cfg.warm};
  ic.engine = cfg.io_engine;
  ic.queue_depth = cfg.queue_depth;
  ic.fail_ring_errno = cfg.fail_ring_errno;
  io_ = std::make_unique<IoPool>(store, ic, clock_,
                                 [this](ReadResult&& r) { on_read(std::move(r)); }, &faults_);
  start_producers(cfg);
}

ThreadedExecutor::ThreadedExecutor(const ThreadedExecutorConfig& cfg) : faults_(cfg.faults), capacity_(cfg.capacity) {
  if (capacity_ == 0) throw std::invalid_argument("ThreadedExecutor: capacity must be positive");
  if (!cfg.producer) throw std::invalid_argument("ThreadedExecutor: an executor without a store needs a producer");
  start_producers(cfg);
}

void ThreadedExecutor::start_producers(const ThreadedExecutorConfig& cfg) {
  if (!cfg.producer) return;
  producer_ = cfg.producer;
  const int n = checked_workers(cfg.produce_workers, "produce.workers");
  for (int i = 0; i < n; ++i) producers_.emplace_back([this] { produce_loop(); });
}

ThreadedExecutor::~ThreadedExecutor() { shutdown(); }

std::uint64_t ThreadedExecutor::page_bytes(const TileStore& store) {
  std::uint64_t page = 0;
  for (std::uint32_t i = 0; i < store.layer_count(); ++i) page += store.tile_bytes(i);
  return page;
}

std::uint64_t ThreadedExecutor::reserved_pages(const TileStore& store, const ThreadedExecutorConfig& cfg) {
  if (cfg.tile_memory_bytes == 0) return 0;
  return std::min<std::uint64_t>(cfg.tile_memory_bytes / page_bytes(store) + cfg.capacity, store.geometry().tiles_per_layer);
}

std::size_t ThreadedExecutor::in_flight() const {
  std::lock_guard lock(m_);
  return jobs_.size() + done_.size();
}

void ThreadedExecutor::restart_clock() {
  std::lock_guard lock(m_);
  if (!jobs_.empty() || !done_.empty()) throw std::logic_error("ThreadedExecutor::restart_clock: jobs in flight");
  clock_.restart();
}

void ThreadedExecutor::submit(const TileJob& job) {
  std::lock_guard lock(m_);
  if (state() != State::running) throw std::logic_error("ThreadedExecutor: submit after shutdown");
  if (jobs_.size() + done_.size() >= capacity_) throw std::logic_error("ThreadedExecutor: submit beyond capacity");
  if (jobs_.count(job.id)) throw std::logic_error("ThreadedExecutor: duplicate request id");
  for (const JobResult& r : done_)
    if (r.id == job.id) throw std::logic_error("ThreadedExecutor: duplicate request id (result not collected)");
  Job j;
  j.job = job;
  j.result.id = job.id;
  j.result.key = job.key;
  j.result.submitted = clock_.now();
  j.result.decoded_bytes = job.decoded_bytes;
  if (job.produce.produced() || (producer_ && producer_->serves(job))) {
    if (!producer_)
      throw std::logic_error(fmt::format("ThreadedExecutor: tile (layer {}, level {}, x {}, y {}) is produced, and the executor has no "
                                         "producer (ThreadedExecutorConfig::producer): it is not in the store",
                                         job.key.layer(), job.key.level(), job.key.x(), job.key.y()));
    j.state = JobState::produce;
    j.result.read_start = j.result.read_end = j.result.decode_start = j.result.decode_end = j.result.submitted;
    jobs_.emplace(job.id, std::move(j));
    if (!produce_q_.push(job.id, job.priority, TileJob(job))) {
      jobs_.erase(job.id);
      throw std::logic_error("ThreadedExecutor: the production queue refused a job");
    }
    return;
  }
  if (!io_)
    throw std::logic_error(fmt::format("ThreadedExecutor: tile (layer {}, level {}, x {}, y {}) is read, and the executor has no store",
                                       job.key.layer(), job.key.level(), job.key.x(), job.key.y()));
  jobs_.emplace(job.id, std::move(j));
  if (!io_->submit(ReadRequest{job.id, job.key, job.priority})) {
    jobs_.erase(job.id);
    throw std::logic_error("ThreadedExecutor: the IO pool refused a job");
  }
}

bool ThreadedExecutor::cancel(RequestId id) {
  std::lock_guard lock(m_);
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return false;  // unknown, or completed and waiting for collect()
  Job& j = it->second;
  switch (j.state) {
    case JobState::io:
      if (io_->cancel(id)) {
        jobs_.erase(it);
        return true;
      }
      j.state = JobState::io_cancelled;  // being read: pay the read, skip the decode
      return false;
    case JobState::io_cancelled:
      return false;
    case JobState::decode:
      if (decode_->cancel(id)) finish(it, JobOutcome::cancelled, Fault::none, {});
      return false;  // decoding: it finishes as ready
    case JobState::produce:
      if (produce_q_.remove(id)) {  // not started: dropped, no cost, no result
        jobs_.erase(it);
        return true;
      }
      return false;  // producing: it finishes as ready
  }
  return false;
}

void ThreadedExecutor::finish(std::unordered_map<RequestId, Job>::iterator it, JobOutcome outcome, Fault fault,
                              const std::string& error) {
  JobResult& r = it->second.result;
  r.outcome = outcome;
  r.fault = fault;
  // The completion time, stamped under the lock so the completion list is in time order.
  r.decode_end = clock_.now();
  if (fault != Fault::none && !error.empty()) {
    bool seen = false;
    for (const auto& e : fault_examples_) seen |= e.rfind(std::string(fault_name(fault)) + ": ", 0) == 0;
    if (!seen) fault_examples_.push_back(std::string(fault_name(fault)) + ": " + error);
  }
  if (fault != Fault::none) {
    TileFaults& t = faulted_[r.key];
    t.key = r.key;
    ++t.in_a_row;
    t.fault = fault;
    t.error = error;
  } else if (outcome == JobOutcome::ready) {
    faulted_.erase(r.key);
  }
  done_.push_back(std::move(r));
  jobs_.erase(it);
  done_cv_.notify_all();
}

void ThreadedExecutor::on_read(ReadResult&& rr) {
  std::lock_guard lock(m_);
  auto it = jobs_.find(rr.id);
  if (it == jobs_.end()) return;  // cannot happen: a job leaves only through finish or a queued cancel
  Job& j = it->second;
  j.result.read_start = rr.read_start;
  j.result.read_end = rr.read_end;
  j.result.bytes_read = rr.bytes_read;
  j.result.decode_start = j.result.decode_end = rr.read_end;
  if (rr.fault != Fault::none) return finish(it, JobOutcome::failed, rr.fault, rr.error);
  if (j.state == JobState::io_cancelled || state() != State::running) return finish(it, JobOutcome::cancelled, Fault::none, {});
  j.state = JobState::decode;
  DecodeTask t{rr.id, rr.key, rr.priority, std::move(rr.record), static_cast<std::size_t>(rr.bytes_read)};
  if (!decode_->submit(t)) finish(it, JobOutcome::cancelled, Fault::none, {});  // shutting down
}

void ThreadedExecutor::on_decoded(DecodeResult&& dr) {
  std::lock_guard lock(m_);
  auto it = jobs_.find(dr.id);
  if (it == jobs_.end()) return;
  JobResult& r = it->second.result;
  r.decode_start = dr.decode_start;
  r.decode_end = dr.decode_end;
  if (dr.fault != Fault::none) return finish(it, JobOutcome::failed, dr.fault, dr.error);
  r.data = std::move(dr.data);
  finish(it, JobOutcome::ready, Fault::none, {});
}

void ThreadedExecutor::produce_loop() {
  while (auto item = produce_q_.pop_wait()) {
    const Ticks start = clock_.now();
    auto data = std::make_shared<TileData>();
    data->key = item->task.key;
    std::string error;
    try {
      producer_->produce(item->task, *data);
    } catch (const std::exception& e) {
      error = e.what()[0] ? e.what() : "the producer threw";
    } catch (...) {
      error = "the producer threw";
    }
    std::lock_guard lock(m_);
    auto it = jobs_.find(item->id);
    if (it == jobs_.end()) continue;  // cannot happen: a job being produced leaves only here
    it->second.result.decode_start = start;
    if (!error.empty()) {
      finish(it, JobOutcome::failed, Fault::decode_error, error);
      continue;
    }
    it->second.result.data = std::move(data);
    finish(it, JobOutcome::ready, Fault::none, {});
  }
}

void ThreadedExecutor::collect(Ticks until, std::vector<JobResult>& out) {
  std::lock_guard lock(m_);
  while (!done_.empty() && done_.front().decode_end <= until) {
    out.push_back(std::move(done_.front()));
    done_.pop_front();
  }
}

void ThreadedExecutor::shutdown() {
  State expected = State::running;
  if (!state_.compare_exchange_strong(expected, State::stopping, std::memory_order_acq_rel)) {
    // Another caller is stopping or has stopped: wait until it is done.
    while (state() != State::stopped) std::this_thread::yield();
    return;
  }
  // Queued reads never start: they complete as cancelled with nothing read.
  if (io_)
    for (const ReadRequest& q : io_->stop()) {
      std::lock_guard lock(m_);
      auto it = jobs_.find(q.id);
      if (it != jobs_.end()) finish(it, JobOutcome::cancelled, Fault::none, {});
    }
  // Reads that finished during the stop skipped their decode (on_read sees stopping); decodes
  // still queued are dropped as cancelled (their reads were paid); decodes under way finish.
  if (decode_)
    for (RequestId id : decode_->stop()) {
      std::lock_guard lock(m_);
      auto it = jobs_.find(id);
      if (it != jobs_.end()) finish(it, JobOutcome::cancelled, Fault::none, {});
    }
  // Queued productions never start: cancelled; productions under way finish.
  for (const auto& q : produce_q_.close()) {
    std::lock_guard lock(m_);
    auto it = jobs_.find(q.id);
    if (it != jobs_.end()) finish(it, JobOutcome::cancelled, Fault::none, {});
  }
  for (std::thread& t : producers_) t.join();
  state_.store(State::stopped, std::memory_order_release);
}

bool ThreadedExecutor::wait_for_results(std::size_t n, std::chrono::milliseconds timeout) {
  std::unique_lock lock(m_);
  return done_cv_.wait_for(lock, timeout, [&] { return done_.size() >= n; });
}

std::vector<std::string> ThreadedExecutor::fault_examples() const {
  std::lock_guard lock(m_);
  return fault_examples_;
}

std::vector<ThreadedExecutor::TileFaults> ThreadedExecutor::faulted_tiles() const {
  std::vector<TileFaults> out;
  {
    std::lock_guard lock(m_);
    for (const auto& [k, t] : faulted_) out.push_back(t);
  }
  std::sort(out.begin(), out.end(), [](const TileFaults& a, const TileFaults& b) { return a.key < b.key; });
  return out;
}

}  // namespace vtsim
