#include "rilod/service_setup.h"

#include "dds/participant.h"
#include "hal/replay/replay_source.h"
#include "rilod/fault_injection.h"

namespace rilo {

ServiceOptions serviceOptions(const ServiceConfig& cfg) {
  ServiceOptions so;
  so.p_w_anchors = uwbAnchorsById(cfg.anchors);
  so.localizer = localizerParams(cfg);
  so.participant.domain_id = cfg.dds.domain_id;
  if (cfg.dds.loopback_only) so.participant.config_xml = dds::loopbackConfigXml();
  if (!cfg.dds.cyclone_config_file.empty()) so.participant.config_xml = "file://" + cfg.dds.cyclone_config_file.string();
  so.publisher.topics = cfg.dds.topics;
  so.publisher.frames = cfg.dds.frames;
  so.publisher.stamp_clock = cfg.dds.stamp_clock;
  so.queue_capacity = cfg.realtime.queue_capacity;
  // The odometry's body rate is a gyro sample less the bias: the IMU model's
  // white noise, and the bias's start prior (a bound: the smoother narrows it).
  so.predictor.gravity_m_s2 = so.localizer.graph.imu.gravity_m_s2;
  so.predictor.gyro_noise_density = so.localizer.graph.imu.gyro_noise_density;
  so.predictor.gyro_bias_sigma = so.localizer.graph.first_gyro_bias_sigma;
  // Nothing real-time upstream of a fast replay: the source waits for the
  // estimator instead of losing samples.
  so.backpressure = cfg.sources.mode == SourceMode::kReplay && cfg.sources.replay.pace == ReplayPace::kAsFastAsPossible;
  so.status_period_s = static_cast<double>(cfg.status.period_ns) * 1e-9;
  so.sensor_silence_s = static_cast<double>(cfg.status.imu_timeout_ns) * 1e-9;
  so.ranging_silence_s = static_cast<double>(cfg.status.range_timeout_ns) * 1e-9;
  return so;
}

LocalizerParams localizerParams(const ServiceConfig& cfg) {
  LocalizerParams lp = localizerParams(cfg.estimator);
  lp.graph.p_w_ultrasonic = ultrasonicBeaconsById(cfg.anchors);  // for ultrasonic ranges
  if (cfg.sources.mode == SourceMode::kHardware && !cfg.estimator.input_screen_imu_bounds_given) {
    // Beyond the BMI263's configured full scale (5 % for its scale error) a
    // sample is a decoding fault, not a motion.
    const bmi263::Bmi263Config& imu = cfg.sources.hardware.imu.bmi263;
    lp.screen.max_accel_m_s2 = bmi263::accelRangeG(imu.accel_range) * 9.80665 * 1.05;
    lp.screen.max_gyro_rad_s = bmi263::gyroRangeDps(imu.gyro_range) * (3.14159265358979323846 / 180.0) * 1.05;
  }
  return lp;
}

LocalizerParams localizerParams(const EstimatorConfig& e) {
  LocalizerParams lp;
  lp.graph = e.graph;
  lp.graph.p_w_ultrasonic.clear();
  lp.smoother = e.smoother;
  lp.stream = e.stream;
  lp.init.window_s = e.init_window_s;
  lp.init.max_outside_anchors_m = e.init_max_outside_anchors_m;
  lp.init.heavy_nlos_after_s = e.init_heavy_nlos_after_s;
  lp.init_attempt_budget_s = e.init_attempt_budget_s;
  lp.height_band = e.height_band;
  lp.vertical_speed_sigma_m_s = e.vertical_speed_sigma_m_s;
  lp.zero_velocity_sigma_m_s = e.zero_velocity_sigma_m_s;
  lp.max_outside_anchors_m = e.max_outside_anchors_m;
  lp.flagged_excess.quantile = e.flagged_excess_quantile;
  lp.los_gap.enabled = e.los_gap_calibration;
  lp.rx_level_envelope.enabled = e.rx_level_indicator;
  lp.nlos_memory.window_s = e.nlos_memory_s;
  lp.with_tdoa = e.with_tdoa;
  lp.screen = e.input_screen;
  return lp;
}

std::unique_ptr<SampleSource> makeReplaySource(const ReplaySourceConfig& replay) {
  ReplayOptions ro;
  ro.pacing = replay.pace == ReplayPace::kRealTime ? ReplayOptions::Pacing::kRealTime
                                                   : ReplayOptions::Pacing::kAsFastAsPossible;
  ro.speed = replay.speed;
  ro.shift_to_now = replay.shift_to_now && ro.pacing == ReplayOptions::Pacing::kRealTime;
  ro.loop = replay.loop;
  std::unique_ptr<SampleSource> source = std::make_unique<ReplaySource>(replay.path, ro);
  if (!replay.faults.empty()) source = std::make_unique<FaultInjectingSource>(std::move(source), replay.faults);
  return source;
}

}  // namespace rilo
