#include "stream/exec/sim_executor.h"

#include <cmath>
#include <stdexcept>

namespace vtsim {

const char* fault_name(Fault f) {
  switch (f) {
    case Fault::none: return "none";
    case Fault::io_error: return "io_error";
    case Fault::short_read: return "short_read";
    case Fault::checksum: return "checksum";
    case Fault::decode_error: return "decode_error";
    case Fault::bad_record: return "bad_record";
  }
  return "unknown";
}

SimExecutor::SimExecutor(const DiskModel& disk, const DecodeModel& decode, std::size_t capacity,
                         SimFaultModel faults, const ProduceModel& produce)
    : disk_(disk), decode_(decode), produce_(produce), capacity_(capacity), faults_(faults) {
  if (capacity_ == 0) throw std::invalid_argument("SimExecutor: capacity must be positive");
}

Ticks SimExecutor::produce_ticks(const ProduceModel& m, const ProduceWork& w) {
  return static_cast<Ticks>(std::llround(produce_ns(m, w)));
}

void SimExecutor::submit(const TileJob& job) {
  if (jobs_.count(job.id)) throw std::logic_error("SimExecutor: duplicate request id");
  Job j;
  j.job = job;
  j.seq = next_seq_++;
  j.result.id = job.id;
  j.result.key = job.key;
  j.result.submitted = now_;
  j.result.decoded_bytes = job.decoded_bytes;
  if (job.produce.produced()) {
    // No disk: the read is empty at the submission time, no fault is drawn.
    j.stage = Stage::produce_queue;
    j.result.read_start = j.result.read_end = j.result.decode_start = j.result.decode_end = now_;
    produce_queue_.emplace(QueueKey{job.priority, j.seq}, job.id);
    jobs_.emplace(job.id, std::move(j));
    start_produce_jobs();
    return;
  }
  disk_queue_.emplace(QueueKey{job.priority, j.seq}, job.id);
  jobs_.emplace(job.id, std::move(j));
  start_disk_jobs();
}

bool SimExecutor::cancel(RequestId id) {
  auto it = jobs_.find(id);
  if (it == jobs_.end()) return false;
  Job& j = it->second;
  if (j.stage == Stage::disk_queue || j.stage == Stage::produce_queue) {
    (j.stage == Stage::disk_queue ? disk_queue_ : produce_queue_).erase(QueueKey{j.job.priority, j.seq});
    jobs_.erase(it);
    return true;
  }
  j.cancelled = true;  // reading: decode will be skipped; decoding or producing: finishes as ready
  return false;
}

void SimExecutor::start_disk_jobs() {
  while (!disk_queue_.empty() && (disk_.channels <= 0 || disk_active_ < disk_slots(disk_))) {
    const RequestId id = disk_queue_.begin()->second;
    disk_queue_.erase(disk_queue_.begin());
    Job& j = jobs_.at(id);
    j.stage = Stage::disk_latency;
    j.result.read_start = now_;
    j.faults = faults_.next(j.job.key);
    ++disk_active_;
    const Ticks latency = static_cast<Ticks>(disk_.latency_us * 1000.0 + 0.5) + j.faults.delay;
    events_.push(now_ + latency, Event{Ev::latency_done, id});
  }
}

void SimExecutor::start_decode_jobs() {
  while (!decode_queue_.empty() && (decode_.workers <= 0 || decode_active_ < decode_.workers)) {
    const RequestId id = decode_queue_.begin()->second;
    decode_queue_.erase(decode_queue_.begin());
    Job& j = jobs_.at(id);
    j.stage = Stage::decoding;
    j.result.decode_start = now_;
    ++decode_active_;
    const Ticks fixed = static_cast<Ticks>(decode_.per_tile_us * 1000.0 + 0.5);
    const double bps = decode_.throughput_MBps > 0 ? decode_.throughput_MBps * 1e6 : 0.0;
    events_.push(now_ + fixed + transfer_ticks(j.job.decoded_bytes, bps), Event{Ev::decode_done, id});
  }
}

void SimExecutor::start_produce_jobs() {
  while (!produce_queue_.empty() && (produce_.workers <= 0 || produce_active_ < produce_.workers)) {
    const RequestId id = produce_queue_.begin()->second;
    produce_queue_.erase(produce_queue_.begin());
    Job& j = jobs_.at(id);
    j.stage = Stage::producing;
    j.result.decode_start = now_;
    ++produce_active_;
    const Ticks dur = produce_ticks(produce_, j.job.produce);
    produce_busy_ += dur;
    events_.push(now_ + dur, Event{Ev::produce_done, id});
  }
}

void SimExecutor::finish(Job& j, std::vector<JobResult>& out) {
  out.push_back(j.result);
  const RequestId id = j.job.id;  // j dies with the erase
  jobs_.erase(id);
}

void SimExecutor::collect(Ticks until, std::vector<JobResult>& out) {
  if (until < now_) throw std::logic_error("SimExecutor::collect: time went backwards");
  while (!events_.empty() && events_.next_time() <= until) {
    const auto ev = events_.pop();
    now_ = ev.time;
    Job& j = jobs_.at(ev.payload.id);
    switch (ev.payload.kind) {
      case Ev::latency_done: {
        j.stage = Stage::disk_transfer;
        const double bps = disk_.bandwidth_MBps > 0 ? disk_.bandwidth_MBps * 1e6 : 0.0;
        const Ticks start = bus_free_ > now_ ? bus_free_ : now_;
        const Ticks dur = transfer_ticks(j.job.disk_bytes, bps);
        bus_free_ = start + dur;
        bus_busy_ += dur;
        events_.push(bus_free_, Event{Ev::transfer_done, j.job.id});
        break;
      }
      case Ev::transfer_done: {
        --disk_active_;
        j.result.read_end = now_;
        j.result.bytes_read = j.job.disk_bytes;
        j.result.decode_start = j.result.decode_end = now_;
        if (j.faults.fault == Fault::io_error || j.faults.fault == Fault::short_read) {
          j.result.outcome = JobOutcome::failed;
          j.result.fault = j.faults.fault;
          // EIO delivers nothing; a short read half the record (as the IO pool's injection).
          j.result.bytes_read = j.faults.fault == Fault::short_read ? j.job.disk_bytes / 2 : 0;
          finish(j, out);
        } else if (j.cancelled) {
          j.result.outcome = JobOutcome::cancelled;
          finish(j, out);
        } else {
          j.stage = Stage::decode_queue;
          decode_queue_.emplace(QueueKey{j.job.priority, j.seq}, j.job.id);
          start_decode_jobs();
        }
        start_disk_jobs();
        break;
      }
      case Ev::decode_done: {
        --decode_active_;
        j.result.decode_end = now_;
        j.result.outcome = j.faults.fault == Fault::checksum ? JobOutcome::failed : JobOutcome::ready;
        j.result.fault = j.faults.fault == Fault::checksum ? Fault::checksum : Fault::none;
        finish(j, out);
        start_decode_jobs();
        break;
      }
      case Ev::produce_done: {
        --produce_active_;
        j.result.decode_end = now_;
        j.result.outcome = JobOutcome::ready;
        finish(j, out);
        start_produce_jobs();
        break;
      }
    }
  }
  now_ = until;
}

}  // namespace vtsim
