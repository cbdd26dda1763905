#pragma once
// The physical screen in front of the estimator (issue 37): one place, used
// by the Localizer, so the replay and the service drop the same rows for the
// same reasons. A row no sensor of this kind can produce (a negative or
// kilometre range, an acceleration beyond any full scale, a stamp behind its
// stream or years ahead of the IMU) is dropped and counted by reason, never
// handed to the estimator: one far-future stamp used to plan a state every
// 0.5 s up to it (memory exhaustion) and impossible values were fused.
#include <array>
#include <cstdint>
#include <string_view>

#include "sensors/samples.h"

namespace rilo {

struct InputScreenParams {
  /// Two-way and ultrasonic ranges must lie in (0, max_range_m] (m), TDoA
  /// differences within +-max_range_m: a DW3000 link closes at ~100-200 m
  /// outdoors, and 0 or below is a firmware's error value, not a distance.
  double max_range_m = 300.0;
  /// IMU samples beyond these (per axis) are not measurements: the BMI263's
  /// largest full scales (16 g, 2000 dps) with 5 % margin.
  double max_accel_m_s2 = 16.0 * 9.80665 * 1.05;
  double max_gyro_rad_s = 2000.0 * 3.14159265358979323846 / 180.0 * 1.05;
  /// A measurement stamped this far (s) ahead of the newest IMU sample is
  /// far-future (before any IMU: ahead of its own stream, confirmed as below).
  double max_time_jump_s = 5.0;
  /// An IMU stamp this far (s) ahead of the previous one is a time jump:
  /// dropped unless the next jump_confirmations samples continue from it (a
  /// real gap, e.g. a paused device: the localizer then re-initializes on
  /// the IMU gap); a lone bad stamp is dropped and the stream goes on. The
  /// localizer's max_imu_gap_s (1 s): a shorter bad step would end tracking.
  double max_imu_jump_s = 1.0;
  /// 0: a jump is taken at once (rilod's Localizer, behind an entrance that
  /// confirmed it already).
  int jump_confirmations = 3;

  void validate() const;
};

/// One stream's forward stamp jumps: a stamp more than max_jump_ns ahead of
/// the stream's newest is held back (the caller drops it) until
/// `confirmations` samples in a row continue from it; then it is taken. A
/// sample back on the old timeline cancels the candidate, so one bad stamp
/// costs one sample. Allocation-free; also rilod's entrance check per source.
class StampJumpGuard {
 public:
  enum class Verdict { kTake, kTakeJump, kHold };
  /// A confirming sample must follow the previous one by at least this (ns):
  /// 0.1 ms, well below any sensor's period here (IMU 0.6 ms at 1600 Hz).
  static constexpr std::int64_t kMinConfirmationStepNs = 100'000;
  /// `newest_ns`: the stream's newest taken stamp; t_ns after it.
  Verdict judge(std::int64_t newest_ns, std::int64_t t_ns, std::int64_t max_jump_ns, int confirmations) noexcept;
  /// A sample at or before the stream's newest: any candidate was a bad stamp.
  void cancel() noexcept { seen_ = 0; }

 private:
  int seen_ = 0;
  std::int64_t candidate_ns_ = 0;
};

enum class InputDrop : int {
  kNotFinite = 0,        ///< a NaN or infinite value or stamp
  kOutOfBounds,          ///< a range or TDoA value outside the screen's bounds
  kBeyondFullScale,      ///< an IMU sample beyond max_accel_m_s2 / max_gyro_rad_s
  kNonMonotonic,         ///< at or before the previous accepted row of its stream
  kFarFuture,            ///< beyond max_time_jump_s ahead of the IMU (or an unconfirmed IMU jump)
  kCount
};

/// The JSON / log name of a reason ("not_finite", "out_of_bounds", ...).
std::string_view inputDropName(InputDrop reason);

struct InputDropCounts {
  std::array<std::uint64_t, static_cast<int>(InputDrop::kCount)> by_reason{};
  std::uint64_t time_jumps = 0;  ///< IMU time jumps accepted after confirmation (faults, not drops)
  std::uint64_t operator[](InputDrop r) const { return by_reason[static_cast<int>(r)]; }
  std::uint64_t total() const;
};

class InputScreen {
 public:
  explicit InputScreen(InputScreenParams params = {});

  /// Whether the row may reach the estimator; a refused row is counted.
  bool admit(const ImuSample& s);
  bool admit(const RangeSample& s);
  bool admit(const TdoaSample& s);
  bool admit(const UltrasonicSample& s);

  const InputDropCounts& dropped() const { return counts_; }

  /// The value checks alone (no stamps): kCount when the sample is physical.
  static InputDrop judgeValue(const ImuSample& s, const InputScreenParams& p) noexcept;
  static InputDrop judgeValue(const RangeSample& s, const InputScreenParams& p) noexcept;
  static InputDrop judgeValue(const TdoaSample& s, const InputScreenParams& p) noexcept;
  static InputDrop judgeValue(const UltrasonicSample& s, const InputScreenParams& p) noexcept;
  const InputScreenParams& params() const { return params_; }

 private:
  struct Stream {
    bool seen = false;
    std::int64_t newest_ns = 0;
    StampJumpGuard jump;
  };
  bool drop(InputDrop reason);
  /// Stamp checks of a measurement row against its stream and the IMU.
  bool admitStamp(Stream& stream, std::int64_t t_ns);

  InputScreenParams params_;
  std::int64_t max_jump_ns_ = 0;
  std::int64_t max_imu_jump_ns_ = 0;
  InputDropCounts counts_;
  Stream imu_, range_, tdoa_, ultrasonic_;
};

}  // namespace rilo
