#pragma once
// Discrete-event queue for the simulated clock: events ordered by (time, sequence number), so two
// events at the same tick run in the order they were scheduled and every run is bit-for-bit
// reproducible. O(log n) push/pop (binary heap). Single-threaded.
#include <cstdint>
#include <queue>
#include <vector>

#include "core/time.h"

namespace vtsim {

template <class Payload>
class EventQueue {
 public:
  struct Event {
    Ticks time;
    std::uint64_t seq;
    Payload payload;
  };

  void push(Ticks time, Payload p) { heap_.push(Event{time, next_seq_++, std::move(p)}); }
  bool empty() const { return heap_.empty(); }
  std::size_t size() const { return heap_.size(); }
  // Time of the earliest event; only when !empty().
  Ticks next_time() const { return heap_.top().time; }
  Event pop() {
    Event e = heap_.top();
    heap_.pop();
    return e;
  }

 private:
  struct Later {
    bool operator()(const Event& a, const Event& b) const {
      return a.time != b.time ? a.time > b.time : a.seq > b.seq;
    }
  };
  std::priority_queue<Event, std::vector<Event>, Later> heap_;
  std::uint64_t next_seq_ = 0;
};

}  // namespace vtsim
