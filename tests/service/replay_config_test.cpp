// `rilo replay --config`: the replay runs the estimator rilod derives from
// its configuration (service_setup.h localizerParams), not the replay's own
// defaults, on the recording's device where its meta.yaml describes it (IMU
// noise densities, lever arms), and explicit replay settings still override
// them.
#include <gtest/gtest.h>

#include <string>

#include "evaluation/replay_run.h"
#include "hal/recording/recording_reader.h"
#include "rilod/config.h"
#include "rilod/service_setup.h"
#include "service/service_test_support.h"

namespace rilo {
namespace {

// A replay configuration whose estimator differs from every replay default
// and from the demo recording's meta.yaml (lever arm [0.06, 0, 0.1], its
// own IMU densities).
const std::string kConfig =
    "sources:\n"
    "  mode: replay\n"
    "  replay:\n"
    "    path: rec\n"
    "anchors:\n"
    "  - {id: 0, x: 0, y: 0, z: 2.5}\n"
    "  - {id: 1, x: 6, y: 0, z: 1.0}\n"
    "  - {id: 2, x: 6, y: 5, z: 2.5}\n"
    "  - {id: 3, x: 0, y: 5, z: 1.0, kind: ultrasonic}\n"
    "imu:\n"
    "  gyro_noise_density: 5.0e-4\n"
    "estimator:\n"
    "  smoother: isam2\n"
    "  lag_s: 7.0\n"
    "  range:\n"
    "    noise_model: huber\n"
    "    sigma_m: 0.07\n"
    "    lever_arm_m: [0.0, 0.0, 0.2]\n"
    "  height_band:\n"
    "    min_height_m: 1.1\n";

ServiceConfig config() { return parseServiceConfig(kConfig, "test.yaml"); }

const Recording& demo() {
  static const Recording rec = readRecording(testing::sourceDir() / "tests" / "data" / "office-demo");
  return rec;
}

TEST(ServiceLocalizerParams, CarryTheEstimatorAndImuSectionsAndTheUltrasonicBeacons) {
  const LocalizerParams lp = localizerParams(config());
  EXPECT_EQ(lp.smoother.method, SmootherParams::Method::kGaussNewton);
  EXPECT_DOUBLE_EQ(lp.smoother.lag_s, 7.0);
  EXPECT_EQ(lp.graph.range_loss, "huber");
  EXPECT_DOUBLE_EQ(lp.graph.range_noise.sigma_m, 0.07);
  EXPECT_DOUBLE_EQ(lp.graph.imu.gyro_noise_density, 5.0e-4);
  EXPECT_TRUE(lp.graph.p_b_tag.isApprox(Vec3(0.0, 0.0, 0.2)));
  EXPECT_DOUBLE_EQ(lp.height_band.min_height_m, 1.1);
  ASSERT_EQ(lp.graph.p_w_ultrasonic.size(), 4u);  // indexed by anchor id
  EXPECT_TRUE(lp.graph.p_w_ultrasonic[3].isApprox(Vec3(0.0, 5.0, 1.0)));
  // The service assembles its Localizer from the same function.
  const ServiceOptions so = serviceOptions(config());
  EXPECT_DOUBLE_EQ(so.localizer.graph.range_noise.sigma_m, 0.07);
  EXPECT_DOUBLE_EQ(so.localizer.smoother.lag_s, 7.0);
}

TEST(ReplayWithServiceParams, TakesTheServicesEstimatorOnTheRecordingsDevice) {
  const Recording& rec = demo();
  ASSERT_TRUE(rec.meta.uwb_lever_arm_m.has_value());
  ASSERT_TRUE(rec.meta.gyro_noise_density.has_value());
  ReplaySettings own;
  const LocalizerParams replay_own = localizerParamsFor(rec, own);
  EXPECT_TRUE(replay_own.graph.p_b_tag.isApprox(*rec.meta.uwb_lever_arm_m));
  EXPECT_DOUBLE_EQ(replay_own.graph.imu.gyro_noise_density, *rec.meta.gyro_noise_density);

  ReplaySettings s;
  s.service_params = localizerParams(config());
  s.smoother = "isam2";
  s.noise = "huber";
  s.lag_s = 7.0;
  const LocalizerParams lp = localizerParamsFor(rec, s);
  // The device as the recording states it...
  EXPECT_TRUE(lp.graph.p_b_tag.isApprox(*rec.meta.uwb_lever_arm_m));
  EXPECT_DOUBLE_EQ(lp.graph.imu.gyro_noise_density, *rec.meta.gyro_noise_density);
  EXPECT_DOUBLE_EQ(lp.graph.imu.accel_noise_density, *rec.meta.accel_noise_density);
  // ... the configuration's where it says nothing, or when told to ...
  ASSERT_EQ(rec.tags.size(), 1u);  // the simulator states its antenna in tags.csv too
  ASSERT_EQ(lp.graph.tag_lever_arms.size(), 1u);
  EXPECT_EQ(lp.graph.tag_lever_arms[0].tag_id, rec.tags[0].id);
  EXPECT_TRUE(lp.graph.tag_lever_arms[0].p_b_m.isApprox(rec.tags[0].p_b_tag));
  Recording silent = rec;
  silent.meta.uwb_lever_arm_m.reset();
  silent.meta.gyro_noise_density.reset();
  silent.tags.clear();
  const LocalizerParams from_silent = localizerParamsFor(silent, s);
  EXPECT_TRUE(from_silent.graph.p_b_tag.isApprox(Vec3(0.0, 0.0, 0.2)));
  EXPECT_DOUBLE_EQ(from_silent.graph.imu.gyro_noise_density, 5.0e-4);
  EXPECT_DOUBLE_EQ(from_silent.graph.imu.accel_noise_density, *rec.meta.accel_noise_density);
  ReplaySettings config_device = s;
  config_device.device_from_recording = false;
  const LocalizerParams from_config = localizerParamsFor(rec, config_device);
  EXPECT_TRUE(from_config.graph.p_b_tag.isApprox(Vec3(0.0, 0.0, 0.2)));
  EXPECT_DOUBLE_EQ(from_config.graph.imu.gyro_noise_density, 5.0e-4);
  // ... and the estimator always the configuration's.
  EXPECT_DOUBLE_EQ(lp.graph.range_noise.sigma_m, 0.07);
  EXPECT_DOUBLE_EQ(lp.height_band.min_height_m, 1.1);
  EXPECT_EQ(lp.smoother.method, SmootherParams::Method::kGaussNewton);
  EXPECT_DOUBLE_EQ(lp.smoother.lag_s, 7.0);
  // The recording's beacons, not the configuration's (the demo has none).
  EXPECT_TRUE(lp.graph.p_w_ultrasonic.empty());

  // Explicit settings still override the service's.
  s.range_sigma_m = 0.2;
  s.smoother = "dogleg";
  s.lag_s = 3.0;
  const LocalizerParams overridden = localizerParamsFor(rec, s);
  EXPECT_DOUBLE_EQ(overridden.graph.range_noise.sigma_m, 0.2);
  EXPECT_EQ(overridden.smoother.method, SmootherParams::Method::kDogleg);
  EXPECT_DOUBLE_EQ(overridden.smoother.lag_s, 3.0);
}

TEST(ReplayWithServiceParams, TdoaSettingsComeFromTheConfigurationUnlessGiven) {
  Recording rec = demo();
  rec.tdoa.push_back(TdoaSample{rec.imu.front().t_ns, 0, 1, 0.5});
  // The replay's own vertical speed default for TDoA data...
  EXPECT_EQ(localizerParamsFor(rec, ReplaySettings()).vertical_speed_sigma_m_s, kTdoaVerticalSpeedSigmaMs);

  ServiceConfig cfg = config();
  cfg.estimator.with_tdoa.state_window_ns = 30'000'000;
  cfg.estimator.with_tdoa.dynamic_covariance = false;
  ReplaySettings s;
  s.service_params = localizerParams(cfg);
  const LocalizerParams lp = localizerParamsFor(rec, s);
  EXPECT_EQ(lp.with_tdoa.state_window_ns, 30'000'000);
  EXPECT_FALSE(lp.with_tdoa.dynamic_covariance);
  EXPECT_EQ(lp.graph.same_state_window_ns, cfg.estimator.graph.same_state_window_ns);
  EXPECT_FALSE(lp.vertical_speed_sigma_m_s.has_value());  // ... gives way to the configuration's "auto"

  s.same_state_window_ms = 12.0;  // for every kind of data
  s.dynamic_covariance = true;
  s.vertical_speed_sigma_m_s = 0.1;
  const LocalizerParams set = localizerParamsFor(rec, s);
  EXPECT_EQ(set.graph.same_state_window_ns, 12'000'000);
  EXPECT_EQ(set.with_tdoa.state_window_ns, 0);
  EXPECT_TRUE(set.stream.dynamic_covariance.enabled);
  EXPECT_TRUE(set.with_tdoa.dynamic_covariance);
  EXPECT_EQ(set.vertical_speed_sigma_m_s, 0.1);
}

}  // namespace
}  // namespace rilo
