#include "devices/emulation/virtual_time.h"

#include <limits>

namespace rilo::emu {

void VirtualClock::schedule(std::int64_t t_ns, std::function<void()> action) {
  events_.emplace(std::make_pair(t_ns < now_ns_ ? now_ns_ : t_ns, sequence_++), std::move(action));
}

void VirtualClock::advanceTo(std::int64_t t_ns) {
  while (!events_.empty() && events_.begin()->first.first <= t_ns) {
    const auto first = events_.begin();
    const std::int64_t event_ns = first->first.first;
    std::function<void()> action = std::move(first->second);
    events_.erase(first);
    if (event_ns > now_ns_) now_ns_ = event_ns;
    action();  // may schedule further events
  }
  if (t_ns > now_ns_) now_ns_ = t_ns;
}

std::int64_t VirtualClock::nextEventNs() const {
  return events_.empty() ? std::numeric_limits<std::int64_t>::max() : events_.begin()->first.first;
}

void EmulatedInterruptLine::setLevel(bool high) {
  if (high && !level_ && edges_.size() < kKernelQueueDepth) {
    const std::int64_t latency_ns = jitter_ns_ ? jitter_ns_() : 0;
    edges_.push_back(hal::EdgeEvent{clock_.nowNs() + latency_ns, true});
  }
  level_ = high;
}

hal::WaitResult EmulatedInterruptLine::waitEdge(std::chrono::nanoseconds timeout, hal::EdgeEvent& event,
                                                std::error_code& error) noexcept {
  if (fail_count_ > 0) {
    --fail_count_;
    error = fail_error_;
    return hal::WaitResult::kError;
  }
  const std::int64_t deadline_ns = clock_.nowNs() + timeout.count();
  while (edges_.empty()) {
    const std::int64_t next_ns = clock_.nextEventNs();
    if (next_ns > deadline_ns) {
      clock_.advanceTo(deadline_ns);
      return hal::WaitResult::kTimeout;
    }
    clock_.advanceTo(next_ns);
  }
  event = edges_.front();
  edges_.pop_front();
  // The waiter wakes no earlier than the edge's (jittered) timestamp.
  if (event.t_ns > clock_.nowNs()) clock_.advanceTo(event.t_ns);
  return hal::WaitResult::kEdge;
}

std::error_code EmulatedOutputLine::set(bool high) noexcept {
  const bool changed = high != level_;
  level_ = high;
  if (changed && on_change_) on_change_(high);
  return {};
}

}  // namespace rilo::emu
