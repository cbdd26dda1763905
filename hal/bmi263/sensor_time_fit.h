#pragma once
// Host time of IMU samples from the device's SENSORTIME counter.
//
// The IMU stamps nothing in host time; what we have per sample is
//   - its sample tick S (unwrapped SENSORTIME, exact, on the IMU oscillator),
//   - the kernel time h of the data-ready edge, h = t_true(S) + latency,
//     latency >= 0 (IRQ and GPIO-controller latency are one-sided).
// The model is t_host(S) = a + b * S over a sliding window (b absorbs the
// oscillator's rate error and its slow drift). Because every latency is
// positive, the line we want is the LOWER envelope of the points (S, h), not a
// least-squares line (which would be biased by the mean latency, tens to
// hundreds of microseconds, and pulled by scheduling outliers).
//
// Estimator: the linear programme of Moon, Skelly and Towsley ("Estimation
// and removal of clock skew from network delay measurements", 1999):
//   minimise sum_i (h_i - a - b S_i)  subject to  h_i >= a + b S_i  for all i.
// Its optimum is the edge of the lower convex hull of the window's points
// that spans the mean tick; the hull is computed in O(n) (monotone chain,
// ticks arrive in order). Properties we rely on:
//   - error is set by the SMALLEST latencies in the window, not the typical
//     ones: with n points the best ones are close to the minimum latency;
//   - large positive outliers (a late wake-up) cannot move the line at all;
//   - a point BELOW the line (impossible with one-sided latency, so a glitch
//     or a mis-paired edge) would pull it down: such points are rejected
//     once the fit is warm (negative_outlier_ns).
// The fit estimates a + (minimum latency): the constant part of the latency is
// not observable from the data and is removed with a configured offset by the
// caller (Bmi263Config::sample_time_offset_ns).
//
// Until the window spans min_span_ticks the slope is held at its nominal
// value (39062.5 ns per tick) and only the offset is fitted (lower envelope of
// h - b_nom * S), so early samples already get sensible times.
//
// No allocation after construction; add() is O(1) except every refit_every
// accepted points, when the hull is rebuilt in O(window).
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rilo::bmi263 {

struct SensorTimeFitConfig {
  std::size_t window = 2048;                ///< points kept (2.56 s at 800 Hz)
  std::int64_t max_span_ticks = 256'000;    ///< and at most this span (10 s of ticks)
  std::int64_t min_span_ticks = 12'800;     ///< fit the slope once the window spans 0.5 s
  std::size_t refit_every = 8;              ///< accepted points between hull rebuilds
  double max_rate_error = 0.02;             ///< |b / b_nominal - 1| beyond this: slope not trusted
  std::int64_t negative_outlier_ns = 100'000;  ///< points this far below a warm fit are rejected
  std::int64_t positive_step_ns = 5'000'000;   ///< all of the last reset_after points this far above: reset
  std::size_t reset_after = 32;             ///< consecutive rejected / stepped points before a reset
  void validate() const;                    ///< std::invalid_argument naming the field
};

/// Unwraps the 24-bit SENSORTIME. The number of whole wraps between two
/// readings is taken from the host time elapsed between them, so gaps longer
/// than one wrap (655 s, e.g. a stalled reader) are unwrapped correctly too.
class SensorTimeUnwrapper {
 public:
  /// Unwrapped tick of `raw24` read at about host time `host_ns`.
  std::int64_t unwrap(std::uint32_t raw24, std::int64_t host_ns) noexcept;
  void reset() noexcept { has_last_ = false; }

 private:
  bool has_last_ = false;
  std::int64_t last_tick_ = 0;
  std::uint32_t last_raw_ = 0;
  std::int64_t last_host_ns_ = 0;
};

class SensorTimeFit {
 public:
  enum class AddResult {
    kAccepted,          ///< the point entered the window
    kRejectedOutlier,   ///< below the warm fit by more than negative_outlier_ns
    kRejectedOrder,     ///< tick not after the previous point
    kReset,             ///< the fit was restarted from this point (step detected)
  };

  explicit SensorTimeFit(SensorTimeFitConfig config = {});

  void reset() noexcept;
  /// Add (tick, host time of the edge). Ticks must increase.
  AddResult add(std::int64_t tick, std::int64_t host_ns) noexcept;

  bool hasEstimate() const noexcept { return has_fit_; }
  /// The slope is fitted (window spans min_span_ticks), not nominal.
  bool slopeFitted() const noexcept { return slope_fitted_; }
  /// Host time (ns) of `tick` on the current line. Requires hasEstimate().
  std::int64_t hostTimeNs(std::int64_t tick) const noexcept;
  /// Fitted rate of the IMU oscillator relative to nominal, in ppm (positive:
  /// the IMU counts fast, so a tick lasts less host time).
  double ratePpm() const noexcept;
  /// The last slope fit was outside max_rate_error (the nominal slope is used).
  bool rateOutOfBounds() const noexcept { return rate_out_of_bounds_; }
  std::size_t size() const noexcept { return count_; }
  const SensorTimeFitConfig& config() const noexcept { return config_; }

 private:
  struct Point {
    std::int64_t tick;
    std::int64_t host_ns;
  };
  const Point& at(std::size_t i) const noexcept { return points_[(head_ + i) % points_.size()]; }
  void push(const Point& p) noexcept;
  void popOldest() noexcept;
  void refit() noexcept;

  SensorTimeFitConfig config_;
  std::vector<Point> points_;       // ring buffer, chronological from head_
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  std::vector<double> hull_x_;      // scratch for the hull (preallocated)
  std::vector<double> hull_y_;
  std::size_t since_refit_ = 0;
  std::size_t consecutive_rejected_ = 0;
  std::size_t consecutive_high_ = 0;

  // Current line: host = ref_host_ns_ + offset_ns_ + slope_ns_per_tick_ * (tick - ref_tick_).
  bool has_fit_ = false;
  bool slope_fitted_ = false;
  bool rate_out_of_bounds_ = false;
  std::int64_t ref_tick_ = 0;
  std::int64_t ref_host_ns_ = 0;
  double offset_ns_ = 0.0;
  double slope_ns_per_tick_ = 0.0;
};

}  // namespace rilo::bmi263
