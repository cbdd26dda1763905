#pragma once
// The service's entrance check on every sample of one source, before it is
// queued for the estimator and the output predictor: a sample with a NaN/inf
// value, one repeating its predecessor, or one older than its predecessor is
// dropped (and counted by the caller), so the estimator never sees what its
// input contract rejects (RangeImuGraphStream throws on non-increasing IMU
// time, non-finite values and measurements older than the previous one; the
// Localizer turns that into a tracking failure and re-initializes).
//
// Per stream (IMU, range, TDoA, ultrasonic), against the last ACCEPTED sample:
//  - non-finite: IMU gyro/accel, range_m, diff_m not finite (rssi and
//    first-path power may be NaN: "unknown");
//  - duplicate: IMU at the same t_ns; range/ultrasonic at the same t_ns to the
//    same anchor (and tag); TDoA at the same t_ns for the same anchor pair;
//  - out of order: t_ns before the previous sample's.
// Ranges to different anchors may share a time. A stream whose clock steps
// back stays dropped until it passes its previous time again (counted all the
// while): sources use CLOCK_MONOTONIC, which never does.
//
//
// The estimator's physical screen (estimation/measurements/input_screen.h)
// applies here too, before the odometry publisher sees a sample (issue 37: an
// IMU sample of 1e30 m/s^2 was screened from the estimator but extrapolated
// into the odometry): values beyond its bounds are dropped, and a stamp more
// than its jump bound ahead of its stream is held until the samples after it
// confirm it (a lone bad stamp would otherwise become the stream's last one
// and every real sample after it "out of order").
//
// IMU-rate path: no allocation, no lock, a handful of compares. One per
// source, used by that source's thread only.
#include <cstdint>
#include <limits>

#include "estimation/measurements/input_screen.h"
#include "hal/source.h"

namespace rilo {

enum class SampleVerdict : std::uint8_t {
  kAccept,
  kNonFinite,
  kDuplicate,
  kOutOfOrder,
  kOutOfBounds,      ///< a range or TDoA value outside the screen's bounds
  kBeyondFullScale,  ///< an IMU axis beyond the screen's full scale
  kFarFuture,        ///< a stamp jump not (yet) confirmed by the samples after it
};

class SampleScreen {
 public:
  explicit SampleScreen(const InputScreenParams& params = {});
  /// Judges `sample` and, if accepted, remembers it as its stream's last one.
  /// `newest_imu_ns`: the newest IMU stamp the service took from any source
  /// (kNoImu: none yet). A measurement more than max_time_jump_s ahead of it
  /// is far-future (the IMU leads; a ranging blackout is not a jump); before
  /// any IMU, a measurement's jump is held until its own stream confirms it.
  static constexpr std::int64_t kNoImu = std::numeric_limits<std::int64_t>::min();
  SampleVerdict check(const Sample& sample, std::int64_t newest_imu_ns = kNoImu) noexcept;

 private:
  struct Last {
    bool seen = false;
    std::int64_t t_ns = 0;
    std::uint32_t a = 0, b = 0;  // anchor (and tag, or the TDoA pair's second anchor)
    StampJumpGuard jump;
  };
  /// max_jump_ns < 0: no jump guard (a measurement judged against the IMU instead).
  SampleVerdict order(Last& last, std::int64_t t_ns, std::uint32_t a, std::uint32_t b, bool key_matters,
                      std::int64_t max_jump_ns) noexcept;
  /// The stamp checks of a measurement (see check()).
  SampleVerdict measurement(Last& last, std::int64_t t_ns, std::uint32_t a, std::uint32_t b,
                            std::int64_t newest_imu_ns) noexcept;
  static SampleVerdict verdictOf(InputDrop why) noexcept;

  InputScreenParams params_;
  std::int64_t max_jump_ns_ = 0, max_imu_jump_ns_ = 0;

  Last imu_, range_, tdoa_, ultrasonic_;
};

}  // namespace rilo
