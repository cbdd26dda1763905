#pragma once
// Parameters and counters of the office simulator's UWB TDoA and ultrasonic
// measurements (the second sensor system, IMU-Ultrasonic-UWB paper: "8 UWB anchors ...
// TDoA ... 20 Hz", "4 ultrasonic transceivers ... 10 Hz", down to "a 40%
// packet reception rate"). The models are in office_tdoa.h and
// office_ultrasonic.h; this header only holds plain structs so that
// OfficeScenarioParams and OfficeStats (office_scenario.h) can carry them.
// Both are off by default: an office simulation without them is unchanged.
#include <cstddef>
#include <vector>

#include <Eigen/Core>

namespace rilo::sim {

/// UWB TDoA, TDoA3-like (see office_tdoa.h for the scheme).
struct TdoaParams {
  bool enabled = false;
  double round_rate_hz = 20.0;         ///< rounds per second; every anchor transmits once per round (paper: 20 Hz)
  double packet_reception = 0.95;      ///< P(the tag receives a packet of an anchor it hears); the paper's worst case 0.4
  double sigma_m = 0.15;               ///< LOS noise of the difference (m); Crazyflie LPS TDoA uses 0.15 m
  double nlos_noise_factor = 1.5;      ///< noise multiplier when either path is NLOS
  double anchor_bias_sigma_m = 0.02;   ///< per-anchor antenna-delay residual (m); a difference gets bias_b - bias_a
  double outlier_probability = 0.005;  ///< large multipath error on one of the two paths
  double outlier_scale_m = 2.0;        ///< median of the long outliers beyond 1 m (half-Cauchy)
  double outlier_max_m = 15.0;
  double early_outlier_fraction = 0.1; ///< outliers that are early (that path short by 0.3-1.5 m)
  double hearing_fading_db = 2.0;      ///< fast fading of a packet's level against the sensitivity (dB)
  double max_reference_age_s = 0.0;    ///< oldest reference packet paired with a new one (s); 0 = one round
  bool keep_twr = false;               ///< also run the SS-TWR ranging (range.csv); otherwise TDoA replaces it
};

/// Ultrasonic beacons on the ceiling and a receiver on the body.
struct UltrasonicParams {
  bool enabled = false;
  int beacons = 4;                     ///< paper: 4 ultrasonic transceivers at known locations
  double ping_rate_hz = 10.0;          ///< rounds per second; every beacon pings once per round (paper: 10 Hz)
  double max_range_m = 8.0;            ///< no echo is detected beyond this (m)
  double sigma_m = 0.02;               ///< range noise (m)
  double speed_of_sound_m_s = 343.0;   ///< the speed the receiver assumes (dry air at 20 C)
  /// Ranges come out (1 + e) times the travelled path: the true speed of
  /// sound is speed_of_sound_m_s / (1 + e). About -0.0018 per degree the air
  /// is warmer than assumed.
  double speed_of_sound_scale_error = 0.0;
  double reflection_probability = 0.3; ///< an obstacle (furniture, person, wearer) on the path: reflection, else no range
  double reflection_min_m = 0.10;      ///< reflection excess = min + scale * Exp(1) quantile of a smooth field (m)
  double reflection_scale_m = 0.40;
  double reflection_max_m = 3.0;
  double dropout = 0.02;               ///< pings missed for other reasons (noise, receiver angle)
  double mount_below_ceiling_m = 0.05; ///< beacons hang this far below the ceiling (m)
  Eigen::Vector3d p_b_receiver{0.0, 0.03, 0.14};  ///< receiver in the body frame (m): meta ultrasonic.lever_arm
  bool body_blocking = true;           ///< the wearer blocks beacons behind them (the channel's azimuth/elevation rule)
  double field_length_m = 1.0;         ///< correlation length of the reflection excess along the walk (m)
};

struct TdoaStats {
  std::size_t rounds = 0;
  std::size_t packets = 0;        ///< anchor packets transmitted
  std::size_t heard = 0;          ///< ... strong enough for the tag (mean RSSI + fading >= sensitivity)
  std::size_t received = 0;       ///< ... of those, received (packet_reception)
  std::size_t no_reference = 0;   ///< received, but no recent packet of another anchor to pair with
  std::size_t measurements = 0;
  std::size_t nlos = 0;           ///< measurements with either path NLOS (los == 0)
  std::size_t nlos_a_only = 0;    ///< only the reference path blocked (bias < 0)
  std::size_t nlos_b_only = 0;    ///< only anchor_b's path blocked (bias > 0)
  std::size_t outliers = 0;
  double nlos_path_excess_sum_m = 0.0;  ///< sum of the excess over the NLOS paths of all measurements
  std::size_t nlos_paths = 0;
  double nlos_bias_abs_sum_m = 0.0;     ///< sum of |excess_b - excess_a| over NLOS measurements
  double nlos_bias_abs_max_m = 0.0;
  double duration_s = 0.0;
  std::vector<std::size_t> measurements_per_anchor;  ///< by anchor_b

  double reception() const { return heard ? static_cast<double>(received) / static_cast<double>(heard) : 0.0; }
  double nlosFraction() const {
    return measurements ? static_cast<double>(nlos) / static_cast<double>(measurements) : 0.0;
  }
  double meanNlosPathExcess() const { return nlos_paths ? nlos_path_excess_sum_m / static_cast<double>(nlos_paths) : 0.0; }
  double meanNlosBias() const { return nlos ? nlos_bias_abs_sum_m / static_cast<double>(nlos) : 0.0; }
  double outlierRate() const {
    return measurements ? static_cast<double>(outliers) / static_cast<double>(measurements) : 0.0;
  }
  double measurementsPerSecond() const { return duration_s > 0.0 ? static_cast<double>(measurements) / duration_s : 0.0; }
};

struct UltrasonicStats {
  std::size_t rounds = 0;
  std::size_t pings = 0;
  std::size_t out_of_range = 0;      ///< beyond max_range_m (direct path or echo)
  std::size_t wall_blocked = 0;      ///< a wall between beacon and receiver: no range
  std::size_t obstacle_dropped = 0;  ///< an obstacle on the path and no usable reflection
  std::size_t dropouts = 0;
  std::size_t measurements = 0;
  std::size_t reflections = 0;       ///< measurements of a reflection (los == 0)
  double reflection_excess_sum_m = 0.0;
  double reflection_excess_max_m = 0.0;
  double duration_s = 0.0;
  std::vector<std::size_t> measurements_per_beacon;

  double nlosFraction() const {
    return measurements ? static_cast<double>(reflections) / static_cast<double>(measurements) : 0.0;
  }
  double meanReflectionExcess() const {
    return reflections ? reflection_excess_sum_m / static_cast<double>(reflections) : 0.0;
  }
  double measurementsPerSecond() const { return duration_s > 0.0 ? static_cast<double>(measurements) / duration_s : 0.0; }
};

/// Validate (std::invalid_argument naming the field), enabled or not.
void validate(const TdoaParams& p);
void validate(const UltrasonicParams& p);

}  // namespace rilo::sim
