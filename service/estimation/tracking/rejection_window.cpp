#include "estimation/tracking/rejection_window.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rilo {

RejectionWindow::RejectionWindow(int length, double max_share) : max_share_(max_share) {
  if (length < 1 || length > 1'000'000) throw std::invalid_argument("RejectionWindow length must be in [1, 1e6]");
  if (!(max_share >= 0.0 && max_share < 1.0)) throw std::invalid_argument("RejectionWindow max_share must be in [0, 1)");
  flags_.assign(static_cast<std::size_t>(length), 0);
  limit_ = static_cast<int>(std::floor(max_share * length + 1e-9));
}

bool RejectionWindow::note(bool accepted) {
  const std::size_t k = static_cast<std::size_t>(next_);
  if (filled_ == length()) {
    rejected_ -= flags_[k];
  } else {
    ++filled_;
  }
  flags_[k] = accepted ? 0 : 1;
  rejected_ += flags_[k];
  next_ = (next_ + 1) % length();
  return filled_ == length() && rejected_ > limit_;
}

void RejectionWindow::reset() {
  std::fill(flags_.begin(), flags_.end(), std::uint8_t{0});
  next_ = filled_ = rejected_ = 0;
}

}  // namespace rilo
