#include "rilod/recorder_config.h"

namespace rilo {

RecorderOptions recorderOptions(const ServiceConfig& config) {
  RecorderOptions o;
  o.flush_interval_ns = config.recording.flush_interval_ns;
  o.sync = config.recording.sync;
  o.queue_capacity = config.realtime.queue_capacity;
  return o;
}

RecordingSetup recordingSetup(const ServiceConfig& config) {
  RecordingSetup s;
  const ImuParams& imu = config.estimator.graph.imu;
  RecordingMeta& m = s.meta;
  m.name = "rilod";
  m.description = "raw samples recorded by rilod (" + std::string(toString(config.sources.mode)) + " source), config " +
                  config.file.string();
  m.gravity_m_s2 = imu.gravity_m_s2;
  m.gyro_noise_density = imu.gyro_noise_density;
  m.accel_noise_density = imu.accel_noise_density;
  m.gyro_bias_random_walk = imu.gyro_bias_random_walk;
  m.accel_bias_random_walk = imu.accel_bias_random_walk;
  m.uwb_lever_arm_m = config.estimator.graph.p_b_tag;
  m.ultrasonic_lever_arm_m = config.estimator.graph.p_b_ultrasonic;  // the device's whole geometry, as before 'optional'
  if (config.sources.mode == SourceMode::kHardware) {
    m.imu_rate_hz = bmi263::odrHz(config.sources.hardware.imu.bmi263.odr);
    m.ranging = RangingKind::kSsTwr;
    // The DW3000 stamps its ranges with the configured tag id; a recording
    // knows only tag 0 without tags.csv, and its writer refused every range
    // of any other.
    const std::uint32_t tag_id = config.sources.hardware.uwb.dw3000.tag_id;
    if (tag_id != 0) s.tags.push_back(Tag{tag_id, config.estimator.graph.p_b_tag});
  }
  s.anchors = config.anchors;
  return s;
}

}  // namespace rilo
