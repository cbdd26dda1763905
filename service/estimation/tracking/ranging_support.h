#pragma once
// Whether the tracked estimate is currently held by ranging (two-way ranges,
// TDoA rows, ultrasonic ranges), for checks that judge where the estimate
// is (LocalizerParams::max_outside_anchors_m): IMU-only dead reckoning
// through a ranging gap may drift anywhere (a 30 s blackout went 10.5 m
// outside the anchors and was pulled back once ranging returned), so such
// checks wait until ranging has run without a gap for `grace_ns`.
//
// A gap is a silence longer than `gap_ns`. 3 s, not 1 s: a tag ranging at
// 1 Hz (or thinned to it, range_thinning.h) has 1.0-1.1 s between ranges,
// and a 1 s gap threshold restarted the grace on nearly every one.
#include <algorithm>
#include <cstdint>

namespace rilo {

class RangingSupport {
 public:
  static constexpr std::int64_t kDefaultGapNs = 3'000'000'000;
  static constexpr std::int64_t kDefaultGraceNs = 5'000'000'000;

  explicit RangingSupport(std::int64_t gap_ns = kDefaultGapNs, std::int64_t grace_ns = kDefaultGraceNs)
      : gap_ns_(gap_ns), grace_ns_(grace_ns) {}

  /// A ranging measurement at t_ns reached the tracker (any time order).
  void note(std::int64_t t_ns) noexcept {
    if (!any_ || t_ns - last_ns_ > gap_ns_) since_ns_ = t_ns;
    last_ns_ = any_ ? std::max(last_ns_, t_ns) : t_ns;
    any_ = true;
  }
  /// Whether an estimate at t_ns is held by ranging: the last measurement at
  /// most gap_ns before it, after a stretch without a gap of at least grace_ns.
  bool supports(std::int64_t t_ns) const noexcept {
    return any_ && t_ns - last_ns_ <= gap_ns_ && t_ns - since_ns_ >= grace_ns_;
  }
  /// Tracking (re)started: nothing heard yet.
  void reset() noexcept { any_ = false; }

 private:
  std::int64_t gap_ns_, grace_ns_;
  bool any_ = false;
  std::int64_t since_ns_ = 0;  ///< start of the current stretch without a gap
  std::int64_t last_ns_ = 0;   ///< newest measurement time
};

}  // namespace rilo
