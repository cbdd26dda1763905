#pragma once
// A ranging + IMU session of a person walking through an office: the office
// plan with walls and furniture (office.h; or an open hall with the anchors
// around it, office_hall.h), sparse wall-mounted anchors, the
// walk (walk.h), the radio channel (office_channel.h), a BMI263-class IMU at
// 800 Hz and SS-TWR ranging to the strongest few anchors per cycle.
//
// The result is the same rilo::sim::Scenario as the synthetic scenario
// (range_imu_scenario.h), so the demo, benchmarks and estimators consume it
// unchanged; OfficeSimulation adds the plan, the per-range truth and
// statistics. Seeded and deterministic: the same params give the same samples
// (the random draws do not depend on the standard library, see
// office_random.h; libm may still differ in the last bit between platforms).
// The samples can also be produced one at a time (OfficeImuStream,
// OfficeRangeStream), so long sessions are written to a recording without
// holding them in memory (office_recording.h); both paths give identical
// samples.
//
// Ranging model (SS-TWR):
//  - Cycles of `ranges_per_cycle` slots, one slot every 1/range_rate_hz s, so
//    range_rate_hz is the total rate over all anchors. At the start of a cycle
//    the tag ranks the anchors it hears (mean RSSI above the sensitivity) by
//    RSSI with `selection_fading_db` of fast fading and ranges the strongest
//    ones in order, one per slot. Fewer heard anchors leave slots empty.
//  - A slot's packet is lost with probability packet_loss (no sample).
//  - range = true + excess (NLOS, office_channel.h) + per-anchor calibration
//    bias + noise (range_sigma_m under LOS, times nlos_noise_factor under
//    NLOS) + rarely a large multipath outlier (mostly long, sometimes an early
//    false first path), clamped at >= 0.
//  - rssi_dbm = mean RSSI + fast fading; fp_power_dbm = rssi minus a gap that
//    is small under LOS (~2 dB) and grows with the obstruction loss and the
//    excess under NLOS (the DW1000/DW3000 "RX level - first path" indicator).
//  - los = 1 if nothing obstructed the direct path, 0 otherwise (truth).
// IMU model: as range_imu_scenario (white noise at the given densities,
// random-walk biases with a random initial value), at imu_rate_hz from t0_ns.
#include <cstdint>
#include <memory>
#include <vector>

#include "sim/office.h"
#include "sim/office_channel.h"
#include "sim/office_hall.h"
#include "sim/office_sensor_params.h"
#include "sim/range_imu_scenario.h"
#include "sim/walk.h"

namespace rilo::sim {

/// kDefault: defaultOfficePlan(); kRandom: randomOfficePlan(seed); kHall: an
/// open hall with the anchors around it (office_hall.h).
enum class OfficePlanKind { kDefault, kRandom, kHall };

struct OfficeScenarioParams {
  std::uint64_t seed = 1;
  double duration_s = 60.0;
  OfficePlanKind plan = OfficePlanKind::kDefault;
  AnchorPlacement anchors;                   ///< count, mounting heights (kHall: count and wall offset only)
  HallLayout hall;                           ///< kHall: size, furniture, low and high anchor heights
  WalkParams walk;                           ///< walk.seed and walk.duration_s are set from seed and duration_s
  Eigen::Vector3d p_b_tag{0.06, 0.0, 0.10};  ///< UWB antenna in the body frame (m); tag at ~1.35 m at the default walk.body_height_m
  std::int64_t t0_ns = 1'000'000'000;        ///< time of the first IMU sample

  // IMU (BMI263 class, as range_imu_scenario).
  double imu_rate_hz = 800.0;
  double gravity_m_s2 = 9.81;
  double gyro_noise_density = 2.8e-4;     ///< rad/s/sqrt(Hz)
  double accel_noise_density = 1.6e-3;    ///< m/s^2/sqrt(Hz)
  double gyro_bias_walk = 2.0e-5;         ///< rad/s^2/sqrt(Hz)
  double accel_bias_walk = 2.0e-4;        ///< m/s^3/sqrt(Hz)
  double gyro_bias_init_sigma = 2e-3;     ///< rad/s
  double accel_bias_init_sigma = 0.03;    ///< m/s^2

  // Ranging.
  double range_rate_hz = 40.0;            ///< total ranges per second (all anchors), before packet loss
  int ranges_per_cycle = 4;               ///< strongest anchors ranged per cycle
  double range_sigma_m = 0.10;            ///< LOS noise (m)
  double nlos_noise_factor = 1.5;         ///< noise multiplier under NLOS
  double anchor_bias_sigma_m = 0.02;      ///< per-anchor antenna-delay calibration residual (m)
  double packet_loss = 0.05;              ///< probability a range packet is lost
  /// The receiver reports its first-path power (fp_power_dbm, the NLOS
  /// indicator). false: RX level only, as other modules and firmware (and
  /// the independent office sims of issue 36) report.
  bool report_first_path = true;
  double outlier_probability = 0.005;     ///< large multipath error on any range
  double outlier_scale_m = 2.0;           ///< median of the long outliers beyond 1 m (half-Cauchy)
  double outlier_max_m = 15.0;
  double early_outlier_fraction = 0.1;    ///< outliers that are early (short by 0.3-1.5 m)
  double selection_fading_db = 2.0;       ///< fast fading when ranking anchors per cycle (dB)
  double rssi_fading_db = 1.5;            ///< fast fading of the reported rssi (dB)
  ChannelParams channel;                  ///< path loss, walls, NLOS severity, body shadowing

  // The second system (IMU-Ultrasonic-UWB paper), off by default: UWB TDoA (office_tdoa.h)
  // and ultrasonic beacons (office_ultrasonic.h). They draw from their own
  // random streams, so the IMU and the SS-TWR ranges do not change with them.
  TdoaParams tdoa;
  UltrasonicParams ultrasonic;
};

/// Validates `p` (std::invalid_argument naming the field).
void validate(const OfficeScenarioParams& p);

/// Truth about one simulated range (evaluation and tests only).
struct RangeTruth {
  double true_range_m = 0.0;
  double excess_m = 0.0;       ///< NLOS excess of the channel (m)
  double error_m = 0.0;        ///< range_m - true_range_m (m)
  Obstruction obstruction;
  bool body_shadowed = false;
  bool outlier = false;
  double rssi_mean_dbm = 0.0;
  std::size_t cycle = 0;
};

struct OfficeStats {
  double duration_s = 0.0;
  std::size_t imu_samples = 0;
  std::size_t cycles = 0;
  std::size_t slots = 0;           ///< scheduled ranges (anchors heard and selected)
  std::size_t empty_slots = 0;     ///< slots without a heard anchor
  std::size_t lost = 0;            ///< packets lost
  std::size_t ranges = 0;
  std::size_t nlos = 0;            ///< ranges with los == 0
  std::size_t outliers = 0;
  double nlos_excess_sum_m = 0.0;  ///< sum of the NLOS excess over NLOS ranges
  double nlos_excess_max_m = 0.0;
  std::vector<std::size_t> ranges_per_anchor;
  TdoaStats tdoa;                  ///< filled by writeOfficeRecording when params.tdoa.enabled
  UltrasonicStats ultrasonic;      ///< filled by writeOfficeRecording when params.ultrasonic.enabled

  double nlosFraction() const { return ranges ? static_cast<double>(nlos) / static_cast<double>(ranges) : 0.0; }
  double outlierRate() const { return ranges ? static_cast<double>(outliers) / static_cast<double>(ranges) : 0.0; }
  double rangesPerSecond() const { return duration_s > 0.0 ? static_cast<double>(ranges) / duration_s : 0.0; }
  double meanNlosExcess() const { return nlos ? nlos_excess_sum_m / static_cast<double>(nlos) : 0.0; }
};

/// The deterministic world of a simulation: plan, anchors, walk, channel.
struct OfficeSetup {
  std::shared_ptr<const OfficePlan> plan;
  std::vector<Eigen::Vector3d> p_w_anchors;
  std::shared_ptr<const OfficeWalk> walk;
  std::shared_ptr<const OfficeChannel> channel;
  std::vector<Eigen::Vector3d> p_w_ultrasonic;  ///< ultrasonic beacons (empty unless ultrasonic.enabled)
};
OfficeSetup makeOfficeSetup(const OfficeScenarioParams& p);

/// The plan of p.plan (the hall of p.hall for kHall).
OfficePlan officePlanOf(const OfficeScenarioParams& p);
/// The UWB anchors of `p` in `plan`: placeAnchors, or placeHallAnchors for kHall.
std::vector<Eigen::Vector3d> anchorsOf(const OfficePlan& plan, const OfficeScenarioParams& p);
/// The ultrasonic beacons of `p` in `plan`: placeUltrasonicBeacons, or
/// placeHallUltrasonicBeacons for kHall (whether p.ultrasonic.enabled or not).
std::vector<Eigen::Vector3d> ultrasonicBeaconsOf(const OfficePlan& plan, const OfficeScenarioParams& p);

/// ScenarioParams describing an office simulation (the fields they share; the
/// Markov-chain NLOS fields do not apply: nlos_fraction is set by
/// simulateOffice to the observed fraction of NLOS ranges, nlos_mean_duration_s
/// and nlos_scale_m are NaN, nlos_max_excess_m is the channel's cap).
ScenarioParams scenarioParamsOf(const OfficeScenarioParams& p);

/// IMU samples one at a time, in time order.
class OfficeImuStream {
 public:
  OfficeImuStream(const OfficeScenarioParams& p, std::shared_ptr<const Trajectory> truth);
  /// Next sample and the [accel; gyro] bias in effect for it; false at the end.
  bool next(ImuSample& sample, Eigen::Matrix<double, 6, 1>& bias);
  std::size_t size() const { return count_; }
  std::size_t produced() const { return k_; }
  const Eigen::Vector3d& gyroBias0() const { return gyro_bias0_; }
  const Eigen::Vector3d& accelBias0() const { return accel_bias0_; }

 private:
  OfficeScenarioParams p_;
  std::shared_ptr<const Trajectory> truth_;
  SimRng rng_;
  std::size_t count_ = 0, k_ = 0;
  Eigen::Vector3d b_g_, b_a_, gyro_bias0_, accel_bias0_;
};

/// Range samples one at a time, in time order.
class OfficeRangeStream {
 public:
  OfficeRangeStream(const OfficeScenarioParams& p, const OfficeSetup& setup);
  /// Next range and its truth; false at the end.
  bool next(RangeSample& sample, RangeTruth& truth);
  /// Counters so far (duration_s and imu_samples are not filled here).
  const OfficeStats& stats() const { return stats_; }
  /// Fraction of the session done, in [0, 1].
  double progress() const;

 private:
  OfficeScenarioParams p_;
  OfficeSetup setup_;
  SimRng rng_;
  std::vector<double> anchor_bias_m_;
  std::size_t cycle_ = 0;
  std::size_t slot_ = 0;
  std::vector<std::size_t> selected_;
  double t_cycle_s_ = 0.0;
  bool done_ = false;
  OfficeStats stats_;
};

/// The anchors ranked by RSSI as the tag sees them at `body` (heard ones only:
/// mean RSSI >= sensitivity), strongest first; `fading` (dB per anchor, may
/// be empty = none) is added before ranking. Used by OfficeRangeStream.
std::vector<std::size_t> rankAnchors(const OfficeChannel& channel, const KinematicState& body,
                                     const std::vector<double>& fading_db);

struct OfficeSimulation {
  Scenario scenario;                   ///< truth = the walk
  OfficeSetup setup;
  std::vector<RangeTruth> range_truth; ///< one per scenario.ranges
  OfficeStats stats;
};

/// IMU and SS-TWR ranges in memory. p.tdoa and p.ultrasonic are ignored here
/// (their samples come from OfficeTdoaStream / OfficeUltrasonicStream, and
/// writeOfficeRecording writes them).
OfficeSimulation simulateOffice(const OfficeScenarioParams& p);
inline Scenario simulateOfficeScenario(const OfficeScenarioParams& p) { return simulateOffice(p).scenario; }

}  // namespace rilo::sim
