// Dynamic covariance (measurement_noise.h) per measurement: its table and
// pending buffer are allocated up front; the notes and sigma() never allocate,
// nor does the EKF estimator's per-sample path with it on, once its buffers
// have grown to their working size. (Counting operator new: ekf_alloc_test.cpp.)
#include <gtest/gtest.h>

#include <vector>

#include "estimation/assembly/measurement_noise.h"
#include "estimation/tracking/ekf_estimator.h"
#include "support/new_counter.h"

namespace rilo {
namespace {

using testing::NewCounter;

RangeImuGraphParams twoBeacons() {
  RangeImuGraphParams g;
  g.p_w_ultrasonic = {Vec3(2, 2, 3), Vec3(6, 2, 3)};
  return g;
}

const std::vector<Vec3> kAnchors = {Vec3(0, 0, 2.5), Vec3(8, 0, 0.5), Vec3(8, 8, 2.5), Vec3(0, 8, 0.5)};

TEST(DynamicCovarianceAllocation, NotesAndSigmasDoNotAllocate) {
  DynamicCovarianceOptions options;
  options.enabled = true;
  options.range = true;  // every kind
  options.ultrasonic = true;
  MeasurementNoise noise(kAnchors, twoBeacons(), options);
  const Pose3 T(Mat3::Identity(), Vec3(3, 4, 1.2));
  std::uint64_t news = 0;
  double sum = 0.0;
  {
    NewCounter counter;
    for (std::uint64_t state = 0; state < 200; ++state) {
      for (std::uint32_t a = 0; a < 4; ++a) {
        const Measurement d{Measurement::Kind::kTdoa, 0, a, (a + 1) % 4, 0.01 * static_cast<double>(state % 7)};
        const Measurement u{Measurement::Kind::kUltrasonic, 0, a % 2, 0, 2.5};
        const Measurement r{Measurement::Kind::kRange, 0, a, 0, 4.0};
        sum += noise.sigma(d) + noise.sigma(u) + noise.sigma(r);
        noise.notePrediction(state, 0, d, T, Vec3::Zero());
        noise.notePrediction(state, 0, u, T, Vec3::Zero());
        noise.noteInnovation(r, 0.1 * static_cast<double>(state % 3) - 0.1, 0.01);
      }
      noise.notePostFit(state, Pose3(Mat3::Identity(), Vec3(3.01, 4.0, 1.2)), Vec3::Zero());
    }
    news = counter.count();
  }
  EXPECT_EQ(news, 0u);
  EXPECT_GT(sum, 0.0);
  EXPECT_EQ(noise.residualsFed(), 200u * 12u);
  ASSERT_NE(noise.covariance(), nullptr);
  EXPECT_TRUE(noise.covariance()->estimated(NoiseKey::tdoa(0, 1)));
}

TEST(DynamicCovarianceAllocation, EkfEstimatorPerSampleDoesNotAllocate) {
  const RangeImuGraphParams g = twoBeacons();
  EkfParams params;
  params.dynamic_covariance.enabled = true;
  EkfEstimator e(kAnchors, g, params);
  e.start(0, Pose3(Mat3::Identity(), Vec3(3, 4, 1.2)), Vec3::Zero(), ImuBias());
  ImuSample imu;
  imu.accel_m_s2 = Vec3(0.0, 0.0, 9.81);
  imu.gyro_rad_s = Vec3::Zero();
  std::vector<UpdateStats> stats;
  std::vector<TimedPose> poses;
  stats.reserve(64);
  poses.reserve(64);
  const MeasurementNoise model(kAnchors, g, DynamicCovarianceOptions());
  const Pose3 T(Mat3::Identity(), Vec3(3, 4, 1.2));
  auto feed = [&](int from, int to) {
    for (int k = from; k < to; ++k) {
      imu.t_ns = 5'000'000LL * k;
      e.addImu(imu);
      if (k % 10 == 0) {  // 20 Hz: a TDoA row per anchor pair and an ultrasonic range
        for (std::uint32_t a = 0; a < 4; ++a) {
          Measurement d{Measurement::Kind::kTdoa, imu.t_ns + 1000 * a, a, (a + 1) % 4, 0.0};
          d.value_m = model.predict(d, T) + (a % 2 == 0 ? 0.05 : -0.05);
          e.addMeasurement(d);
        }
        Measurement u{Measurement::Kind::kUltrasonic, imu.t_ns + 5000, static_cast<std::uint32_t>(k / 10 % 2), 0, 0.0};
        u.value_m = model.predict(u, T) + 0.01;
        e.addMeasurement(u);
      }
      stats.clear();
      e.process(&stats);
      poses.clear();
      e.drainSmoothed(poses);
    }
  };
  feed(0, 2000);  // 10 s: buffers at their working size, every link out of its warm-up
  std::uint64_t news = 0;
  {
    NewCounter counter;
    feed(2000, 2400);
    news = counter.count();
  }
  EXPECT_EQ(news, 0u);
  ASSERT_NE(e.measurementNoise().covariance(), nullptr);
  EXPECT_TRUE(e.measurementNoise().covariance()->estimated(NoiseKey::tdoa(0, 1)));
  EXPECT_GT(e.filter().counters().tdoa.accepted, 900u);  // 960 rows
}

}  // namespace
}  // namespace rilo
