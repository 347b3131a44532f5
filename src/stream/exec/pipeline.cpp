#include "stream/exec/pipeline.h"

#include <algorithm>
#include <stdexcept>

namespace vtsim {

Pipeline::Pipeline(const PipelineConfig& cfg, IExecutor& exec, TileSizer sizer)
    : cfg_(cfg), exec_(exec), sizer_(std::move(sizer)), ram_(cfg.ram_bytes) {
  auto hook = [this](TileKey key, RamEntry&, std::uint64_t bytes, LruRemoval reason) {
    if (reason == LruRemoval::kEvicted || reason == LruRemoval::kShrunk) {
      ++counters_.ram_evictions;
      counters_.ram_evicted_bytes += bytes;
      ram_evicted_at_[key] = frame_;
      if (ram_evicted_at_.size() > 65536) {  // forget evictions too old to count as thrash
        for (auto it = ram_evicted_at_.begin(); it != ram_evicted_at_.end();)
          it = frame_ - it->second > cfg_.thrash_frames ? ram_evicted_at_.erase(it) : std::next(it);
      }
    }
  };
  if (cfg_.ram_policy == "lru") {
    ram_.set_hook(hook);
  } else {
    ram_any_ = std::make_unique<PolicyCache<RamEntry>>(cfg_.ram_policy, cfg_.ram_bytes, hook);
  }
}

bool Pipeline::is_failed(TileKey key) const {
  auto it = failed_.find(key);
  if (it == failed_.end()) return false;
  if (cfg_.failed_retry_s <= 0.0) return true;
  return now_ - it->second < seconds_to_ticks(cfg_.failed_retry_s);
}

void Pipeline::begin_frame(int frame, Ticks now) {
  frame_ = frame;
  now_ = now;
  produced_this_frame_ = 0;
  if (ram_any_) ram_any_->begin_frame(frame);
  if (ram_log_) ram_log_->frame_start.push_back(ram_log_->accesses.size());
  results_.clear();
  exec_.collect(now, results_);
  for (auto& r : results_) on_result(r);
}

void Pipeline::drop(TileKey key) {
  auto it = requests_.find(key);
  if (it == requests_.end()) return;
  by_id_.erase(it->second.id);
  requests_.erase(it);
}

void Pipeline::to_ram(Request& q, const std::shared_ptr<const TileData>& data, bool prefetched) {
  if (ram_any_) ram_any_->insert(q.key, RamEntry{data, prefetched}, q.sizes.decoded_bytes);
  else ram_.insert(q.key, RamEntry{data, prefetched}, q.sizes.decoded_bytes);
}

void Pipeline::on_result(JobResult& r) {
  auto idit = by_id_.find(r.id);
  if (idit == by_id_.end()) throw std::logic_error("Pipeline: result for an unknown request");
  const TileKey key = idit->second;
  by_id_.erase(idit);
  Request& q = requests_.at(key);
  if (observer_) observer_->on_job(r, q.prefetch, q.sizes.produce.produced());
  if (r.bytes_read) {
    counters_.disk_bytes_by_level[key.level()] += r.bytes_read;
    counters_.disk_bytes += r.bytes_read;
    ++counters_.disk_reads;
    if (q.prefetch) counters_.prefetch_disk_bytes += r.bytes_read;
  }
  const bool abandoned = q.state == State::cancelling && !q.revived;
  const bool produced = q.sizes.produce.produced();
  switch (r.outcome) {
    case JobOutcome::ready: {
      if (produced) {
        // Rendered for VRAM, not kept in RAM: abandoned, it is gone (needed again: produced again).
        ++counters_.produced;
        counters_.produced_bytes += r.decoded_bytes;
        counters_.produce_ns += static_cast<std::uint64_t>(r.decode_end - r.decode_start);
        if (abandoned) {
          end_unserved(q, q.cancel_time, Unserved::cancelled);
          requests_.erase(key);
          return;
        }
        q.timing = r;
        q.state = State::waiting_upload;
        q.in_ram_time = r.decode_end;
        q.data = std::move(r.data);
        q.revived = false;
        return;
      }
      counters_.decoded_bytes += r.decoded_bytes;
      ++counters_.decodes;
      q.timing = r;
      if (abandoned || q.prefetch) {
        // Nobody waits for it now; keep it in RAM for a later need (the work is already paid).
        if (abandoned && !cfg_.cache_prefetched_on_cancel) {
          ++counters_.cancelled_after_read;
          counters_.wasted_read_bytes += r.bytes_read;
        } else {
          to_ram(q, r.data, q.prefetch);
        }
        if (abandoned) end_unserved(q, q.cancel_time, Unserved::cancelled);
        requests_.erase(key);
        return;
      }
      to_ram(q, r.data, false);
      q.state = State::waiting_upload;
      q.in_ram_time = r.decode_end;
      q.data = std::move(r.data);
      q.revived = false;
      return;
    }
    case JobOutcome::cancelled: {
      if (produced) {
        ++counters_.produce_cancelled;  // only at an executor's shutdown: production never started
      } else {
        ++counters_.cancelled_after_read;
        counters_.wasted_read_bytes += r.bytes_read;
      }
      if (q.state == State::cancelling && q.revived) {
        q.state = State::queued;  // needed again: read it again
        q.revived = false;
      } else {
        end_unserved(q, q.state == State::cancelling ? q.cancel_time : now_, Unserved::cancelled);
        requests_.erase(key);
      }
      return;
    }
    case JobOutcome::failed: {
      ++counters_.faults;
      ++counters_.fault_by_kind[static_cast<int>(r.fault) & 7];
      if (abandoned) {
        end_unserved(q, q.cancel_time, Unserved::cancelled);
        requests_.erase(key);
      } else if (q.attempts <= cfg_.max_retries) {
        ++counters_.retries;
        q.state = State::backoff;
        q.revived = false;
        q.retry_frame = frame_ + cfg_.retry_backoff_frames;
      } else {
        ++counters_.failed_tiles;
        failed_[key] = now_;
        end_unserved(q, now_, Unserved::failed);
        requests_.erase(key);
      }
      return;
    }
  }
}

void Pipeline::set_needs(const std::vector<Need>& needs) {
  for (auto& [k, q] : requests_) q.needed = false;
  for (const Need& n : needs) {
    if (!n.prefetch) ++counters_.needs;
    if (!failed_.empty() && is_failed(n.key)) continue;
    auto it = requests_.find(n.key);
    if (it == requests_.end()) {
      if (n.prefetch) {
        if (ram_contains(n.key)) continue;  // already in RAM: nothing to fetch
      }
      Request q;
      q.sizes = sizer_(n.key);
      if (q.sizes.produce.produced() && n.prefetch) continue;  // prefetch fills RAM; produced tiles skip it
      q.key = n.key;
      q.id = next_id_++;
      q.prefetch = n.prefetch;
      q.priority = n.priority;
      q.needed = true;
      q.needed_frame = frame_;
      q.needed_time = now_;
      if (n.prefetch) {
        ++counters_.prefetch_requests;
        q.state = State::queued;
      } else if (q.sizes.produce.produced()) {
        ++counters_.requests;  // no RAM lookup: a produced tile is never in RAM
        ++counters_.produce_requests;
        q.state = State::queued;
      } else {
        ++counters_.requests;
        record_ram(n.key, q.sizes.decoded_bytes);
        if (const RamEntry* e = ram_get(n.key)) {  // promote: this tile is in use
          ++counters_.ram_hits;
          q.ram_hit = true;
          q.prefetched_entry = e->prefetched;
          if (e->prefetched) ++counters_.prefetch_hits;
          q.data = e->data;
          q.state = State::waiting_upload;
          q.in_ram_time = now_;
        } else {
          ++counters_.ram_misses;
          q.state = State::queued;
          if (!ram_evicted_at_.empty()) {
            auto ev = ram_evicted_at_.find(n.key);
            if (ev != ram_evicted_at_.end()) {
              if (frame_ - ev->second <= cfg_.thrash_frames) ++counters_.ram_thrash;
              ram_evicted_at_.erase(ev);
            }
          }
        }
      }
      if (observer_ && !q.prefetch) observer_->on_request(q.key, frame_, now_, q.ram_hit, q.sizes.produce.produced());
      requests_.emplace(n.key, std::move(q));
      continue;
    }
    Request& q = it->second;
    q.needed = true;
    if (q.prefetch && !n.prefetch) {
      // A look-ahead fetch under way became a demand: latency counts from now.
      q.prefetch = false;
      ++counters_.requests;
      ++counters_.ram_misses;
      ++counters_.prefetch_hits;
      record_ram(n.key, q.sizes.decoded_bytes);
      q.needed_frame = frame_;
      q.needed_time = now_;
      if (observer_) observer_->on_request(q.key, frame_, now_, false, false);
    }
    if (!q.prefetch) q.priority = n.priority;
    if (q.state == State::cancelling) q.revived = true;
  }
  for (auto it = requests_.begin(); it != requests_.end();) {
    Request& q = it->second;
    if (q.needed) {
      ++it;
      continue;
    }
    bool erase = true;
    switch (q.state) {
      case State::queued:
      case State::backoff:
        ++(q.sizes.produce.produced() ? counters_.produce_cancelled : counters_.cancelled_queued);
        break;
      case State::submitted:
        if (exec_.cancel(q.id)) {
          ++(q.sizes.produce.produced() ? counters_.produce_cancelled : counters_.cancelled_queued);
          by_id_.erase(q.id);
        } else {
          q.state = State::cancelling;
          q.cancel_time = now_;
          q.revived = false;
          erase = false;
        }
        break;
      case State::cancelling:
        if (q.revived) q.cancel_time = now_;  // needed again, then not: cancelled again now
        q.revived = false;
        erase = false;
        break;
      case State::waiting_upload:
        ++counters_.dropped_before_upload;
        break;
    }
    if (erase) end_unserved(q, now_, Unserved::cancelled);
    it = erase ? requests_.erase(it) : std::next(it);
  }
}

void Pipeline::dispatch() {
  scratch_.clear();
  for (auto& [k, q] : requests_) {
    if (q.state == State::backoff && q.retry_frame <= frame_) q.state = State::queued;
    if (q.state == State::queued) scratch_.push_back(&q);
  }
  if (!scratch_.empty() && exec_.in_flight() < exec_.capacity()) {
    std::sort(scratch_.begin(), scratch_.end(), [](const Request* a, const Request* b) {
      return a->priority != b->priority ? a->priority < b->priority : a->key < b->key;
    });
    const int produce_budget = cfg_.produce_tiles_per_frame;
    for (Request* q : scratch_) {
      if (exec_.in_flight() >= exec_.capacity()) break;
      if (q->sizes.produce.produced()) {
        if (produce_budget > 0 && produced_this_frame_ >= produce_budget) {
          ++counters_.produce_deferred;  // stays queued for a later frame; reads may still go
          continue;
        }
        ++produced_this_frame_;
        ++counters_.produce_submitted;
      }
      q->state = State::submitted;
      ++q->attempts;
      by_id_[q->id] = q->key;
      ++counters_.submitted;
      exec_.submit(TileJob{q->id, q->key, q->sizes.disk_bytes, q->sizes.decoded_bytes,
                           q->prefetch ? kPrefetchPriorityBase + q->priority : q->priority, q->sizes.produce});
    }
  }
  // Work that completes at this very tick (an unconstrained device, a RAM-speed read) is ready for
  // this frame's uploads.
  results_.clear();
  exec_.collect(now_, results_);
  for (auto& r : results_) on_result(r);
}

void Pipeline::take_uploads(const UploadBudget& budget, std::vector<UploadItem>& out) {
  scratch_.clear();
  for (auto& [k, q] : requests_)
    if (q.state == State::waiting_upload) scratch_.push_back(&q);
  std::sort(scratch_.begin(), scratch_.end(), [](const Request* a, const Request* b) {
    return a->priority != b->priority ? a->priority < b->priority : a->key < b->key;
  });
  std::uint64_t bytes = 0;
  int tiles = 0;
  Ticks link = 0;
  for (Request* q : scratch_) {
    if (budget.tiles > 0 && tiles >= budget.tiles) break;
    if (budget.bytes > 0 && bytes + q->sizes.decoded_bytes > budget.bytes) continue;  // a smaller one may fit
    if (budget.link_ticks > 0) {
      const Ticks copy = budget.per_tile_ticks + transfer_ticks(q->sizes.decoded_bytes, budget.link_Bps);
      if (link + copy > budget.link_ticks) continue;  // likewise
      link += copy;
    }
    bytes += q->sizes.decoded_bytes;
    ++tiles;
    UploadItem u;
    u.key = q->key;
    u.bytes = q->sizes.decoded_bytes;
    u.needed_frame = q->needed_frame;
    u.needed_time = q->needed_time;
    u.ram_hit = q->ram_hit;
    u.prefetched = q->prefetched_entry;
    u.produced = q->sizes.produce.produced();
    if (!q->ram_hit) {
      const JobResult& t = q->timing;
      u.queue_ticks = t.read_start - q->needed_time;
      u.io_ticks = t.read_end - t.read_start;
      u.decode_wait_ticks = t.decode_start - t.read_end;
      u.decode_ticks = t.decode_end - t.decode_start;
    }
    u.ram_ticks = now_ - q->in_ram_time;
    u.data = std::move(q->data);
    if (!u.produced) ram_get(q->key);  // used: most recent
    ++counters_.uploads;
    counters_.upload_bytes += u.bytes;
    out.push_back(std::move(u));
  }
  for (const UploadItem& u : out) requests_.erase(u.key);
}

void Pipeline::return_uploads(std::vector<UploadItem>::iterator first, std::vector<UploadItem>::iterator last) {
  for (auto it = first; it != last; ++it) {
    UploadItem& u = *it;
    Request q;
    q.id = next_id_++;
    q.key = u.key;
    q.state = State::waiting_upload;
    q.needed = true;
    q.ram_hit = u.ram_hit;
    q.prefetched_entry = u.prefetched;
    q.priority = 0;
    q.sizes = sizer_(u.key);
    q.sizes.decoded_bytes = u.bytes;
    q.needed_frame = u.needed_frame;
    q.needed_time = u.needed_time;
    q.in_ram_time = now_ - u.ram_ticks;
    q.timing.submitted = u.needed_time;
    q.timing.read_start = u.needed_time + u.queue_ticks;
    q.timing.read_end = q.timing.read_start + u.io_ticks;
    q.timing.decode_start = q.timing.read_end + u.decode_wait_ticks;
    q.timing.decode_end = q.timing.decode_start + u.decode_ticks;
    q.data = std::move(u.data);
    --counters_.uploads;
    counters_.upload_bytes -= u.bytes;
    requests_.insert_or_assign(u.key, std::move(q));
  }
}

void Pipeline::open_demand_requests(Ticks end, std::vector<UnservedRequest>& out) const {
  for (const auto& [k, q] : requests_)
    if (!q.prefetch && !(q.state == State::cancelling && !q.revived)) out.push_back({q.needed_time, end, Unserved::open_at_end});
  // A cancelling request not needed again was cancelled at cancel_time; its job had not returned.
  for (const auto& [k, q] : requests_)
    if (!q.prefetch && q.state == State::cancelling && !q.revived) out.push_back({q.needed_time, q.cancel_time, Unserved::cancelled});
}

std::size_t Pipeline::queued() const {
  std::size_t n = 0;
  for (const auto& [k, q] : requests_) n += q.state == State::queued;
  return n;
}

Backlog Pipeline::backlog(int num_levels) const {
  Backlog b;
  b.bytes_by_level.assign(static_cast<std::size_t>(num_levels), 0);
  b.tiles_by_level.assign(static_cast<std::size_t>(num_levels), 0);
  for (const auto& [k, q] : requests_) {
    if (q.prefetch || q.state == State::cancelling) continue;
    const auto l = static_cast<std::size_t>(k.level());
    if (l >= b.bytes_by_level.size()) continue;
    b.bytes_by_level[l] += q.sizes.decoded_bytes;
    ++b.tiles_by_level[l];
  }
  return b;
}

}  // namespace vtsim
