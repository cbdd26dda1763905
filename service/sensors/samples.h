#pragma once
// Sensor samples as every source emits them (hardware drivers, replay of a
// recording, the simulator). One clock: t_ns on CLOCK_MONOTONIC on the device,
// the recording's clock in replay. Plain values, fixed size, no heap.
#include <cstdint>
#include <limits>

#include <Eigen/Core>

namespace rilo {

struct ImuSample {
  std::int64_t t_ns = 0;                            ///< sample time (ns)
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();   ///< angular rate, body frame (rad/s)
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();   ///< specific force, body frame (m/s^2)
};

struct RangeSample {
  std::int64_t t_ns = 0;     ///< time of the range (ns)
  std::uint32_t anchor_id = 0;
  std::uint32_t tag_id = 0;  ///< antenna on the body: an `id` of tags.csv (0 = the single antenna at uwb.lever_arm)
  double range_m = 0.0;      ///< measured distance (m)
  double rssi_dbm = std::numeric_limits<double>::quiet_NaN();  ///< received power, if known (NaN otherwise)
  int los = -1;              ///< ground truth from a simulator: 1 LOS, 0 NLOS, -1 unknown. Estimators never read it.
  double fp_power_dbm = std::numeric_limits<double>::quiet_NaN();  ///< first-path power, if known (NaN otherwise)
  /// fp_power_dbm was not reported but written by the estimator from the RX
  /// level (Localizer::withRxLevelIndicator): the flag it gives says a path
  /// is attenuated, not how much it is delayed.
  bool fp_from_rx_level = false;
  /// The receiver reported no first-path power and the estimator's mixture
  /// took this anchor's last ranges as NLOS (Localizer, nlos_memory.h): taken
  /// as flagged NLOS at the component's mode.
  bool nlos_from_memory = false;
};

/// Time difference of arrival between two UWB anchors:
/// diff_m = |p - A_b| - |p - A_a| (m), p the tag antenna in world.
struct TdoaSample {
  std::int64_t t_ns = 0;       ///< time of the measurement (ns)
  std::uint32_t anchor_a = 0;  ///< reference anchor
  std::uint32_t anchor_b = 0;
  double diff_m = 0.0;         ///< range difference (m)
  /// The tag's receive diagnostics of the two packets (DW1000/DW3000 RX level
  /// and first-path power, dBm, as RangeSample's); NaN when not reported.
  double rssi_a_dbm = std::numeric_limits<double>::quiet_NaN();
  double fp_power_a_dbm = std::numeric_limits<double>::quiet_NaN();
  double rssi_b_dbm = std::numeric_limits<double>::quiet_NaN();
  double fp_power_b_dbm = std::numeric_limits<double>::quiet_NaN();
  int los = -1;                ///< ground truth: 1 LOS, 0 NLOS, -1 unknown. Estimators never read it.
};

/// Ultrasonic range from the body's ultrasonic receiver to an ultrasonic beacon.
struct UltrasonicSample {
  std::int64_t t_ns = 0;      ///< time of the range (ns)
  std::uint32_t anchor_id = 0;
  double range_m = 0.0;       ///< measured distance (m)
  int los = -1;               ///< ground truth: 1 LOS, 0 NLOS, -1 unknown. Estimators never read it.
};

}  // namespace rilo
