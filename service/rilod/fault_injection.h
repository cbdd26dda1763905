#pragma once
// Fault injection for testing the service end to end: a SampleSource that
// wraps another one (the replay of a recording) and damages its stream the way
// real sensors and drivers do, at given sample times. Configured from
// `sources.replay.faults` (config/README.md); used by the fault tests in
// tests/service/rilod_fault_test.cpp.
//
// Times: at_s is counted in sample time from the first sample the wrapped
// source delivers (any stream), so a fault lands at the same place in the
// data whatever the pace, speed or time shift of the replay.
//
// Kinds:
//  - range_blackout {at_s, duration_s}: every ranging sample (two-way range,
//    TDoA, ultrasonic) with time in [at, at + duration) is dropped.
//  - imu_gap {at_s, duration_s}: every IMU sample in [at, at + duration) is dropped.
//  - duplicate {at_s, count[, stream]}: the first `count` samples of the
//    stream from `at` on are each delivered twice.
//  - out_of_order {at_s, count[, stream]}: the first `count` samples of the
//    stream from `at` on are each held back and delivered right after the
//    next sample of the same kind (IMU after IMU, range after range): that
//    sample arrives older than its predecessor.
//  - non_finite {at_s, count[, stream]}: the first `count` samples of the
//    stream from `at` on get a NaN (even ones) or +inf (odd ones) in their
//    value (IMU: accel x; range, ultrasonic: range_m; TDoA: diff_m).
//  - far_future {at_s, count[, stream]}: the first `count` samples of the
//    stream from `at` on are stamped 28 years later (a clock or driver
//    glitch): the entrance drops each, and the stream goes on.
//  - impossible {at_s, count[, stream]}: the first `count` samples of the
//    stream from `at` on get a value no sensor gives (IMU: accel x 1e30
//    m/s^2; range, ultrasonic: -5 m (even ones) or 1e9 m (odd ones); TDoA:
//    a 1e9 m difference): the estimator's physical screen drops them.
// `stream` (imu, ranging, all; default all) selects which samples a counted
// fault applies to. Faults may overlap; per sample they apply in this order:
// drop windows, non-finite, out of order, duplicate.
//
// Real-time behaviour: per sample no allocation and no lock (the held
// samples live in fixed slots); run() and the counters are for one thread.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "hal/source.h"

namespace rilo {

enum class FaultKind { kRangeBlackout, kImuGap, kDuplicate, kOutOfOrder, kNonFinite, kImpossible, kFarFuture };
enum class FaultStream { kAll, kImu, kRanging };

struct FaultSpec {
  FaultKind kind = FaultKind::kRangeBlackout;
  double at_s = 0.0;          ///< sample time after the first sample (s), >= 0
  double duration_s = 0.0;    ///< range_blackout, imu_gap: length of the window (s), > 0
  std::uint32_t count = 0;    ///< duplicate, out_of_order, non_finite: samples affected, > 0
  FaultStream stream = FaultStream::kAll;  ///< duplicate, out_of_order, non_finite

  /// Window kinds (range_blackout, imu_gap) use duration_s; the others count.
  bool isWindow() const noexcept { return kind == FaultKind::kRangeBlackout || kind == FaultKind::kImuGap; }
  /// Throws std::invalid_argument naming the bad field ("FaultSpec.duration_s ...").
  void validate() const;
};

/// "range_blackout", "imu_gap", "duplicate", "out_of_order", "non_finite".
std::string_view toString(FaultKind kind);
/// "all", "imu", "ranging".
std::string_view toString(FaultStream stream);
/// "range_blackout 30 s at 20 s", "duplicate 5 imu samples at 12 s".
std::string describe(const FaultSpec& fault);

/// What a FaultInjectingSource did to the stream (for tests and the log).
struct InjectedFaults {
  std::uint64_t dropped = 0;     ///< samples removed by drop windows
  std::uint64_t corrupted = 0;   ///< samples given a non-finite value
  std::uint64_t impossible = 0;  ///< samples given an impossible value
  std::uint64_t far_future = 0;  ///< samples stamped 28 years later
  std::uint64_t reordered = 0;   ///< samples delivered after their successor
  std::uint64_t duplicated = 0;  ///< extra copies delivered
};

class FaultInjectingSource final : public SampleSource {
 public:
  /// Throws std::invalid_argument for a null source or an invalid fault.
  FaultInjectingSource(std::unique_ptr<SampleSource> inner, std::vector<FaultSpec> faults);

  /// Runs the wrapped source through the injector. A sample still held back
  /// for out_of_order when the wrapped source ends is delivered then.
  SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override;
  /// The wrapped source's description plus the faults.
  std::string describe() const override;

  const std::vector<FaultSpec>& faults() const noexcept { return faults_; }
  /// What the last run() injected (read after run() returned).
  const InjectedFaults& injected() const noexcept { return injected_; }

 private:
  class Injector;

  std::unique_ptr<SampleSource> inner_;
  std::vector<FaultSpec> faults_;
  InjectedFaults injected_;
};

}  // namespace rilo
