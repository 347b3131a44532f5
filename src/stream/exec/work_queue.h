#pragma once
// The queue in front of the IO pool's and the decode pool's workers: a priority queue (lower
// priority value first, then submission order) with cancellation by request id and a close that
// wakes every waiting worker.
//
// State machine (std::atomic, changed under the mutex): open -> closed. While open, push() adds,
// pop_wait() blocks until there is a task; after close() push() refuses, pop_wait() returns
// nothing at once, and close() hands back what was still queued (so its owner can report it).
//
// Complexity: push, pop, remove O(log n). Thread-safety: every member may be called from any
// thread; tasks move in and out under one mutex; waiting uses a condition variable.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/error.h"
#include "stream/exec/i_executor.h"

namespace vtsim {

template <class Task>
class WorkQueue {
 public:
  enum class State : std::uint8_t { open, closed };
  struct Item {
    RequestId id = 0;
    Task task;
  };

  // false (and `task` is not taken) when the queue is closed or `id` is already queued.
  bool push(RequestId id, std::uint64_t priority, Task&& task) {
    {
      std::lock_guard lock(m_);
      if (state_.load(std::memory_order_relaxed) != State::open || where_.count(id)) return false;
      const Key k{priority, seq_++};
      q_.emplace(k, Item{id, std::move(task)});
      where_.emplace(id, k);
    }
    cv_.notify_one();
    return true;
  }

  // Blocks until a task is available (returns it) or the queue is closed (returns nothing).
  std::optional<Item> pop_wait() {
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return state_.load(std::memory_order_relaxed) != State::open || !q_.empty(); });
    if (state_.load(std::memory_order_relaxed) != State::open) return std::nullopt;
    auto it = q_.begin();
    Item item = std::move(it->second);
    where_.erase(item.id);
    q_.erase(it);
    return item;
  }

  // Takes the first task without waiting; nothing if the queue is empty or closed.
  std::optional<Item> try_pop() {
    std::lock_guard lock(m_);
    if (state_.load(std::memory_order_relaxed) != State::open || q_.empty()) return std::nullopt;
    auto it = q_.begin();
    Item item = std::move(it->second);
    where_.erase(item.id);
    q_.erase(it);
    return item;
  }

  // Cancellation: removes a queued task (returns it); nothing if it is not queued (taken or unknown).
  std::optional<Task> remove(RequestId id) {
    std::lock_guard lock(m_);
    auto w = where_.find(id);
    if (w == where_.end()) return std::nullopt;
    auto it = q_.find(w->second);
    Task t = std::move(it->second.task);
    q_.erase(it);
    where_.erase(w);
    return t;
  }

  // Closes the queue (idempotent), wakes every waiter, returns what was queued in priority order.
  std::vector<Item> close() {
    std::vector<Item> left;
    {
      std::lock_guard lock(m_);
      state_.store(State::closed, std::memory_order_relaxed);
      for (auto& [k, item] : q_) left.push_back(std::move(item));
      q_.clear();
      where_.clear();
    }
    cv_.notify_all();
    closed_cv_.notify_all();
    return left;
  }

  // Waits `d` unless the queue closes first (a slow request must not delay shutdown). Returns
  // false if the queue is closed.
  bool sleep_unless_closed(std::chrono::nanoseconds d) {
    std::unique_lock lock(m_);
    return !closed_cv_.wait_for(lock, d, [&] { return state_.load(std::memory_order_relaxed) != State::open; });
  }

  std::size_t size() const {
    std::lock_guard lock(m_);
    return q_.size();
  }
  State state() const { return state_.load(std::memory_order_relaxed); }

 private:
  using Key = std::pair<std::uint64_t, std::uint64_t>;  // (priority, submission order)
  mutable std::mutex m_;
  std::condition_variable cv_;         // a task arrived or the queue closed (workers)
  std::condition_variable closed_cv_;  // the queue closed (sleep_unless_closed); separate so a
                                       // push's notify_one always reaches a worker
  std::map<Key, Item> q_;                       // guarded by m_
  std::unordered_map<RequestId, Key> where_;    // guarded by m_
  std::uint64_t seq_ = 0;                       // guarded by m_
  std::atomic<State> state_{State::open};       // written under m_; read anywhere
};

// A pool's worker count, checked: InputError naming `field` (the config key) outside 1..1024.
inline int checked_workers(int n, const char* field) {
  if (n < 1 || n > 1024) throw InputError(field, "must be in 1..1024, got " + std::to_string(n));
  return n;
}

// Starts `n` workers running `body` into `out`. If creating one fails, closes `queue` (so the
// started ones return from pop_wait), joins them and rethrows: no joinable thread is left behind.
template <class Task, class Body>
void start_workers(std::vector<std::thread>& out, int n, WorkQueue<Task>& queue, Body body) {
  out.reserve(static_cast<std::size_t>(n));
  try {
    for (int i = 0; i < n; ++i) out.emplace_back(body);
  } catch (...) {
    queue.close();
    for (std::thread& t : out) t.join();
    out.clear();
    throw;
  }
}

}  // namespace vtsim
