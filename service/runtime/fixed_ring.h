#pragma once
// Single-thread ring of the last N values, allocated once: appending to a full
// ring overwrites the oldest value instead of growing or failing, which is what
// a history buffer on the IMU-rate path needs.
#include <cstddef>
#include <memory>
#include <stdexcept>

namespace rilo {

// T: default-constructible, copy assignment that does not throw in practice
// (fixed-size Eigen members do not declare it noexcept, but never throw).
template <typename T>
class FixedRing {
 public:
  /// Throws std::invalid_argument if capacity is 0.
  explicit FixedRing(std::size_t capacity)
      : capacity_(capacity == 0 ? throw std::invalid_argument("FixedRing: capacity must be >= 1") : capacity),
        slots_(std::make_unique<T[]>(capacity_)) {}

  /// Appends `value`; returns true if the ring was full and the oldest value was dropped.
  bool push(const T& value) noexcept {
    if (size_ < capacity_) {
      slots_[physical(size_)] = value;
      ++size_;
      return false;
    }
    slots_[oldest_] = value;  // the oldest slot becomes the newest
    oldest_ = oldest_ + 1 == capacity_ ? 0 : oldest_ + 1;
    return true;
  }

  /// i-th value from the oldest (0) to the newest (size() - 1). Requires i < size().
  const T& operator[](std::size_t i) const noexcept { return slots_[physical(i)]; }
  const T& oldest() const noexcept { return (*this)[0]; }
  const T& newest() const noexcept { return (*this)[size_ - 1]; }

  std::size_t size() const noexcept { return size_; }
  std::size_t capacity() const noexcept { return capacity_; }
  bool empty() const noexcept { return size_ == 0; }
  bool full() const noexcept { return size_ == capacity_; }
  void clear() noexcept {
    size_ = 0;
    oldest_ = 0;
  }

 private:
  std::size_t physical(std::size_t i) const noexcept {
    const std::size_t j = oldest_ + i;  // both < capacity_: no overflow, one subtraction wraps
    return j >= capacity_ ? j - capacity_ : j;
  }

  std::size_t capacity_;
  std::unique_ptr<T[]> slots_;
  std::size_t oldest_ = 0;  ///< physical index of the oldest value
  std::size_t size_ = 0;
};

}  // namespace rilo
