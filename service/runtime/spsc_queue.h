#pragma once
// Lock-free single-producer/single-consumer ring: the hand-off from a sensor
// thread to the estimator. Capacity is fixed at construction (rounded up to a
// power of two) and storage is allocated once, so push/pop never allocate,
// never block and never take a lock. A full queue rejects the push; the
// producer counts the overflow (ServiceStatus::queue_overflows).
//
// Memory ordering: the producer writes the slot, then publishes it with a
// release store of tail_; the consumer's acquire load of tail_ makes the slot
// contents visible. Symmetrically the consumer releases head_ after moving a
// slot out, and the producer's acquire load of head_ guarantees the consumer is
// done with a slot before it is overwritten. Each side caches the other's index
// and re-reads it only when the cache says full/empty, so in steady state each
// operation touches only its own cache line.
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "runtime/cpu_hints.h"

namespace rilo {

template <typename T>
class SpscQueue {
  static_assert(std::is_default_constructible_v<T>, "slots are constructed once, up front");
  static_assert(std::is_nothrow_move_assignable_v<T>,
                "push/pop move-assign slots and must not throw half-way");

 public:
  /// Largest supported capacity (slots); indices are 64-bit and never wrap in practice.
  static constexpr std::size_t kMaxCapacity = std::size_t{1} << 40;

  /// Capacity is min_capacity rounded up to a power of two (masking instead of
  /// modulo). Throws std::invalid_argument if min_capacity is 0 or > kMaxCapacity.
  explicit SpscQueue(std::size_t min_capacity)
      : capacity_(checkedCapacity(min_capacity)),
        mask_(capacity_ - 1),
        slots_(std::make_unique<T[]>(capacity_)) {}

  SpscQueue(const SpscQueue&) = delete;
  SpscQueue& operator=(const SpscQueue&) = delete;

  /// Producer only. False (value untouched) when the queue is full.
  bool tryPush(const T& value) noexcept(std::is_nothrow_copy_assignable_v<T>) {
    return emplaceWith([&](T& slot) { slot = value; });
  }
  bool tryPush(T&& value) noexcept {
    return emplaceWith([&](T& slot) { slot = std::move(value); });
  }

  /// Consumer only. False (out untouched) when the queue is empty.
  bool tryPop(T& out) noexcept {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);  // only we write it
    if (head == tail_cache_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);  // see the producer's slot writes
      if (head == tail_cache_) return false;
    }
    out = std::move(slots_[head & mask_]);
    head_.store(head + 1, std::memory_order_release);  // slot may now be reused
    return true;
  }

  std::size_t capacity() const noexcept { return capacity_; }

  /// Number of queued items as seen at some instant during the call; exact
  /// only when neither side is running. Any thread.
  std::size_t sizeApprox() const noexcept {
    // head first: tail read later is >= it, so the difference is never negative.
    const std::uint64_t head = head_.load(std::memory_order_acquire);
    const std::uint64_t tail = tail_.load(std::memory_order_acquire);
    const std::uint64_t n = tail - head;
    return n > capacity_ ? capacity_ : static_cast<std::size_t>(n);
  }
  bool emptyApprox() const noexcept { return sizeApprox() == 0; }

 private:
  static std::size_t checkedCapacity(std::size_t min_capacity) {
    if (min_capacity == 0 || min_capacity > kMaxCapacity) {
      throw std::invalid_argument("SpscQueue: min_capacity must be in [1, 2^40], got " +
                                  std::to_string(min_capacity));
    }
    return std::bit_ceil(min_capacity);
  }

  template <typename Assign>
  bool emplaceWith(Assign&& assign) {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);  // only we write it
    if (tail - head_cache_ == capacity_) {
      head_cache_ = head_.load(std::memory_order_acquire);  // consumer is done with freed slots
      if (tail - head_cache_ == capacity_) return false;
    }
    assign(slots_[tail & mask_]);
    tail_.store(tail + 1, std::memory_order_release);  // publish the slot
    return true;
  }

  // Read-only after construction: shared by both sides without contention.
  const std::size_t capacity_;
  const std::size_t mask_;
  const std::unique_ptr<T[]> slots_;

  // Producer's line: its index and its cache of the consumer's index.
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> tail_{0};
  std::uint64_t head_cache_ = 0;
  // Consumer's line.
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> head_{0};
  std::uint64_t tail_cache_ = 0;
  // alignas makes sizeof a multiple of the line: nothing else shares the consumer's line.
};

}  // namespace rilo
