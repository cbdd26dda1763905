#pragma once
// A FIFO ring for sample buffers on the IMU-rate path: it grows to the
// working size once and then never allocates.
#include <cstddef>
#include <vector>

namespace rilo {

namespace detail {

/// FIFO ring over a power-of-two buffer that doubles when full and never
/// shrinks: once grown to the working size, push/pop never allocate.
template <class T>
class GrowingRing {
 public:
  explicit GrowingRing(std::size_t initial_capacity = 16) : buf_(roundUpPow2(initial_capacity)) {}
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  std::size_t capacity() const { return buf_.size(); }
  const T& operator[](std::size_t i) const { return buf_[(head_ + i) & (buf_.size() - 1)]; }
  T& operator[](std::size_t i) { return buf_[(head_ + i) & (buf_.size() - 1)]; }
  const T& front() const { return (*this)[0]; }
  T& back() { return (*this)[size_ - 1]; }
  const T& back() const { return (*this)[size_ - 1]; }
  void push_back(const T& v) {
    if (size_ == buf_.size()) grow();
    buf_[(head_ + size_) & (buf_.size() - 1)] = v;
    ++size_;
  }
  void pop_front() {
    head_ = (head_ + 1) & (buf_.size() - 1);
    --size_;
  }
  void pop_front(std::size_t n) {
    head_ = (head_ + n) & (buf_.size() - 1);
    size_ -= n;
  }

 private:
  static std::size_t roundUpPow2(std::size_t n) {
    std::size_t c = 1;
    while (c < n) c <<= 1;
    return c;
  }
  void grow() {
    std::vector<T> bigger(2 * buf_.size());
    for (std::size_t i = 0; i < size_; ++i) bigger[i] = (*this)[i];
    buf_.swap(bigger);
    head_ = 0;
  }

  std::vector<T> buf_;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

}  // namespace detail

}  // namespace rilo
