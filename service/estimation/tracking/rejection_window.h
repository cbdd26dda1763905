#pragma once
// Windowed rejection share: the Localizer's "the estimator no longer agrees
// with its measurements" rule. Each tracking update reports whether its step
// was accepted (UpdateStats::step_accepted: the smoother kept its result, or
// the EKF accepted at least half of a measurement group); the window says
// when more than max_share of the last `length` updates were rejected.
//
// Why a share and not only a run of rejections in a row: a diverged EKF gates
// most measurements, but a lucky group that happens to fit the wrong state now
// and then breaks any run, so the EKF ran metres off for minutes while
// "healthy". The Localizer's default, more than half of 100 updates, separates
// a diverged EKF from a tracking one and from the smoothers; measured:
// docs/noise-models.md, Figures behind the defaults.
//
// Fixed storage (allocated in the constructor); note() never allocates.
#include <cstdint>
#include <vector>

namespace rilo {

class RejectionWindow {
 public:
  /// length: updates in the window (>= 1); max_share in [0, 1): the verdict
  /// is "too many" once the window is full and rejected > max_share * length.
  /// Throws std::invalid_argument naming the parameter otherwise.
  RejectionWindow(int length, double max_share);

  /// Records one update; returns true when the window is full and more than
  /// max_share of it was rejected.
  bool note(bool accepted);
  /// Forgets every update (new tracking run).
  void reset();

  int length() const { return static_cast<int>(flags_.size()); }
  int filled() const { return filled_; }
  int rejected() const { return rejected_; }
  double share() const { return filled_ > 0 ? static_cast<double>(rejected_) / filled_ : 0.0; }
  double maxShare() const { return max_share_; }

 private:
  std::vector<std::uint8_t> flags_;  ///< ring buffer, 1 = rejected
  double max_share_;
  int limit_;  ///< most rejections allowed in a full window
  int next_ = 0, filled_ = 0, rejected_ = 0;
};

}  // namespace rilo
