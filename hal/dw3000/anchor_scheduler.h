#pragma once
// Which anchor to range next, and when. Keeps the strongest N anchors
// ("active") ranged at up to `range_rate_hz` each, polls the others
// ("candidates") one at a time every `rediscovery_period_ns` so an anchor that
// becomes stronger (the tag moved) is swapped in, and backs off exponentially
// from an anchor that stops answering until it is dropped from the active set.
//
// Strength: the smoothed RSSI when the driver knows it; otherwise a
// free-space proxy -20 log10(range) (dB re 1 m), so closer = stronger.
// Pure logic on caller-supplied times: no clock, no I/O, no allocation after
// construction.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace rilo::dw3000 {

struct AnchorSchedulerParams {
  std::size_t max_active = 4;                        ///< N strongest anchors ranged continuously
  double range_rate_hz = 10.0;                       ///< per active anchor
  std::int64_t rediscovery_period_ns = 250'000'000;  ///< one candidate poll per period (set full)
  std::int64_t vacancy_rediscovery_period_ns = 20'000'000;  ///< ... while the set has room
  double hysteresis_db = 3.0;      ///< a candidate must beat the weakest active by this much
  double strength_smoothing = 0.3; ///< EWMA weight of a new strength value of an active anchor (0..1]
  int max_failures = 3;            ///< consecutive failures that drop an active anchor
  std::int64_t backoff_initial_ns = 20'000'000;  ///< first retry delay after a failure
  std::int64_t backoff_max_ns = 1'000'000'000;   ///< retry delay cap
};

class AnchorScheduler {
 public:
  enum class State : std::uint8_t { kUnknown, kActive, kCandidate };

  struct Pick {
    std::size_t index = 0;
    std::int64_t at_ns = std::numeric_limits<std::int64_t>::max();  ///< when it is due
    bool discovery = false;  ///< a poll of a non-active anchor
  };

  /// Throws std::invalid_argument naming the bad parameter.
  AnchorScheduler(std::size_t anchor_count, const AnchorSchedulerParams& params);

  /// The next exchange: the earliest due active anchor, or a discovery poll
  /// (first a sweep over every anchor, then one candidate per period).
  Pick next(std::int64_t now_ns) const noexcept;

  /// A range from anchor `index` at now_ns; `strength_db` as described above.
  void reportSuccess(std::size_t index, std::int64_t now_ns, double strength_db) noexcept;
  /// No usable range from anchor `index`. Returns true if this dropped it
  /// from the active set.
  bool reportFailure(std::size_t index, std::int64_t now_ns) noexcept;

  State state(std::size_t index) const noexcept { return anchors_[index].state; }
  double strengthDb(std::size_t index) const noexcept { return anchors_[index].strength_db; }
  int consecutiveFailures(std::size_t index) const noexcept { return anchors_[index].failures; }
  std::size_t activeCount() const noexcept;
  std::size_t size() const noexcept { return anchors_.size(); }
  /// Delay before the retry after `failures` consecutive failures.
  std::int64_t backoffNs(int failures) const noexcept;
  /// Strength proxy for a range when no RSSI is known.
  static double strengthFromRangeDb(double range_m) noexcept;

 private:
  struct Anchor {
    State state = State::kUnknown;
    double strength_db = -std::numeric_limits<double>::infinity();
    bool has_strength = false;
    int failures = 0;
    std::int64_t next_due_ns = 0;  ///< active anchors only
  };

  std::int64_t periodNs() const noexcept;
  std::size_t weakestActive() const noexcept;  // size() if none
  void promote(std::size_t index, std::int64_t now_ns) noexcept;

  AnchorSchedulerParams params_;
  std::vector<Anchor> anchors_;
  std::int64_t next_rediscovery_ns_ = 0;
  std::size_t rediscovery_cursor_ = 0;  // round-robin position over candidates
};

}  // namespace rilo::dw3000
