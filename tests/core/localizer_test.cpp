// The online pipeline end to end on simulated walks: initialization from
// scratch, tracking, failure detection and re-initialization.
#include "estimation/tracking/localizer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "sim/office_scenario.h"
#include "sim/range_imu_scenario.h"
#include "support/online_run.h"

namespace rilo {
namespace {

LocalizerParams paramsFor(const sim::Scenario& s) { return testing::localizerParamsFor(s); }

/// A 60 s office walk as recorded and with the receiver's first-path power removed.
struct WithAndWithoutFirstPath {
  sim::Scenario with_fp, without_fp;
};
WithAndWithoutFirstPath officeWithAndWithoutFirstPath(std::uint64_t seed) {
  sim::OfficeScenarioParams op;
  op.seed = seed;
  op.duration_s = 60.0;
  WithAndWithoutFirstPath out{sim::simulateOfficeScenario(op), {}};
  op.report_first_path = false;
  out.without_fp = sim::simulateOfficeScenario(op);
  return out;
}

struct FeedResult {
  double mean_error_m = 0.0;
  double mean_height_error_m = 0.0;      ///< signed, estimate - truth
  double mean_abs_height_error_m = 0.0;
  int tracked_updates = 0;
  std::int64_t first_track_ns = -1;
};

/// Feeds the scenario in time order, dropping IMU samples in [gap_from, gap_to);
/// `on_estimate` sees the newest estimate after every tracked update,
/// `on_initializing` is called after every sample while not tracking.
FeedResult feed(const sim::Scenario& s, Localizer& localizer, std::int64_t gap_from_ns = -1, std::int64_t gap_to_ns = -1,
                const std::function<void(const StateEstimate&)>& on_estimate = {},
                const std::function<void()>& on_initializing = {}) {
  FeedResult run;
  std::size_t i = 0, r = 0;
  double sum = 0.0, sum_dz = 0.0, sum_abs_dz = 0.0;
  while (i < s.imu.size() || r < s.ranges.size()) {
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      localizer.addRange(s.ranges[r++]);
    } else {
      const ImuSample& m = s.imu[i++];
      if (m.t_ns >= gap_from_ns && m.t_ns < gap_to_ns) continue;
      localizer.addImu(m);
    }
    const int updates = localizer.process();
    if (!localizer.tracking() && on_initializing) on_initializing();
    if (updates > 0 && localizer.tracking()) {
      if (run.first_track_ns < 0) run.first_track_ns = localizer.latest().t_ns;
      const Vec3 e = localizer.latest().T_w_b.p - s.truthAt(localizer.latest().t_ns).T_w_b.p;
      sum += e.norm();
      sum_dz += e.z();
      sum_abs_dz += std::abs(e.z());
      ++run.tracked_updates;
      if (on_estimate) on_estimate(localizer.latest());
    }
  }
  if (run.tracked_updates > 0) {
    run.mean_error_m = sum / run.tracked_updates;
    run.mean_height_error_m = sum_dz / run.tracked_updates;
    run.mean_abs_height_error_m = sum_abs_dz / run.tracked_updates;
  }
  return run;
}

TEST(Localizer, InitializesFromScratchAndTracks) {
  sim::ScenarioParams sp;
  sp.duration_s = 40.0;
  sp.seed = 3;
  const sim::Scenario s = sim::simulateScenario(sp);
  Localizer localizer(s.p_w_anchors, paramsFor(s));
  const FeedResult run = feed(s, localizer);
  ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
  EXPECT_EQ(localizer.initializations(), 1u);
  EXPECT_EQ(localizer.reinitializations(), 0u) << localizer.lastFailure();
  EXPECT_GT(run.tracked_updates, 400);
  EXPECT_EQ(localizer.trackingVerticalSpeedSigma(), kTwoWayVerticalSpeedSigmaMs);  // "auto" with two-way ranges
  // The initializer waits until yaw and position are determined (18 s on
  // this seed's slow start); it must not wait for ever.
  EXPECT_LT(static_cast<double>(run.first_track_ns - s.imu.front().t_ns) * 1e-9, 25.0);
  // Tracks without diverging. (Accuracy is measured by the issue 4 report:
  // online error on these synthetic walks is 0.2-0.7 m today, see the notes.)
  EXPECT_LT(run.mean_error_m, 1.0);
  const auto cov = localizer.latestPoseCovariance();
  ASSERT_TRUE(cov.has_value());
  EXPECT_GT(cov->diagonal().tail<3>().minCoeff(), 0.0);
  EXPECT_LT(cov->diagonal().tail<3>().maxCoeff(), 1.0);
  const auto v_cov = localizer.latestVelocityCovariance();
  ASSERT_TRUE(v_cov.has_value());
  ASSERT_EQ(v_cov->rows(), 3);
  EXPECT_GT(v_cov->diagonal().minCoeff(), 0.0);
  EXPECT_LT(v_cov->diagonal().maxCoeff(), 1.0);
}

// Flagged ranges' component scale follows the two-way ranging rate of the
// data tracking starts on (RangeNoiseParams::flagged_scale_reference_hz):
// widened at 40 Hz, the default at 4 Hz, and a configured scale is kept.
TEST(Localizer, FlaggedScaleFollowsTheRangingRateUnlessConfigured) {
  struct Case {
    double range_hz;
    std::optional<double> configured_m;
    double expected_lo, expected_hi;
  };
  for (const Case& c : {Case{40.0, std::nullopt, 1.8, 2.0}, Case{4.0, std::nullopt, 1.0, 1.0},
                        Case{40.0, 0.7, 0.7, 0.7}}) {
    SCOPED_TRACE(::testing::Message() << c.range_hz << " Hz, configured " << c.configured_m.value_or(-1.0));
    sim::ScenarioParams sp;
    sp.duration_s = 30.0;
    sp.seed = 3;
    sp.range_rate_hz = c.range_hz;
    const sim::Scenario s = sim::simulateScenario(sp);
    LocalizerParams p = paramsFor(s);
    p.graph.range_noise.flagged_nlos_scale_m = c.configured_m;
    Localizer localizer(s.p_w_anchors, p);
    EXPECT_EQ(localizer.trackingFlaggedScaleM(), 0.0) << "before tracking";
    feed(s, localizer);
    ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
    // 40 Hz less packet loss: sqrt(~36-40 Hz / 10 Hz).
    EXPECT_GE(localizer.trackingFlaggedScaleM(), c.expected_lo);
    EXPECT_LE(localizer.trackingFlaggedScaleM(), c.expected_hi);
  }
}

TEST(Localizer, ImuBlackoutEndsTrackingAndItRecovers) {
  sim::ScenarioParams sp;
  sp.duration_s = 45.0;
  sp.seed = 4;
  const sim::Scenario s = sim::simulateScenario(sp);
  Localizer localizer(s.p_w_anchors, paramsFor(s));
  const std::int64_t t0 = s.imu.front().t_ns;
  feed(s, localizer, t0 + 20'000'000'000, t0 + 23'000'000'000);  // 3 s without IMU
  EXPECT_EQ(localizer.reinitializations(), 1u);
  EXPECT_NE(localizer.lastFailure().find("IMU silent"), std::string::npos) << localizer.lastFailure();
  EXPECT_TRUE(localizer.tracking()) << "not re-initialized: " << localizer.initStatus().message;
  EXPECT_EQ(localizer.initializations(), 2u);
}

TEST(Localizer, ShortImuGapIsBridgedWithoutCorruptingTheBiases) {
  // 0.9 s without IMU samples (below max_imu_gap_s): the missing motion is
  // uncertain (ImuParams gap sigmas), so ranging re-anchors the state and the
  // biases stay put. Integrated as exactly known, this gap pushed the gyro
  // bias to 5-9x its value and ended tracking 23 s later.
  sim::ScenarioParams sp;
  sp.duration_s = 60.0;
  sp.seed = 5;
  const sim::Scenario s = sim::simulateScenario(sp);
  Localizer localizer(s.p_w_anchors, paramsFor(s));
  const std::int64_t gap_from = s.imu.front().t_ns + 30'000'000'000;
  const FeedResult run = feed(s, localizer, gap_from, gap_from + 900'000'000);
  ASSERT_TRUE(localizer.tracking()) << localizer.lastFailure();
  EXPECT_EQ(localizer.reinitializations(), 0u) << localizer.lastFailure();
  EXPECT_LT(run.mean_error_m, 0.6);  // 0.45 m measured; 0.42 m without the gap
  EXPECT_LT(localizer.latest().bias.gyro.cwiseAbs().maxCoeff(), 0.02);  // 0.009 rad/s measured
}

TEST(Localizer, AbsurdImuWhileTrackingIsAFailureNotACrash) {
  // A gyro reading of 500 rad/s makes one preintegration window rotate more
  // than it supports: the estimator throws, the localizer must recover.
  sim::ScenarioParams sp;
  sp.duration_s = 45.0;
  sp.seed = 4;
  sim::Scenario s = sim::simulateScenario(sp);
  const std::int64_t t0 = s.imu.front().t_ns;
  for (ImuSample& m : s.imu) {
    if (m.t_ns >= t0 + 25'000'000'000 && m.t_ns < t0 + 25'200'000'000) m.gyro_rad_s = Vec3(500.0, 0.0, 0.0);
  }
  // Past the default screen (2000 dps): widen it so the reading reaches the
  // estimator, as from a part with a larger full scale.
  LocalizerParams p = paramsFor(s);
  p.screen.max_gyro_rad_s = 1000.0;
  Localizer localizer(s.p_w_anchors, p);
  EXPECT_NO_THROW(feed(s, localizer));
  EXPECT_GE(localizer.reinitializations(), 1u);
  EXPECT_FALSE(localizer.lastFailure().empty());
  std::printf("last failure: %s\n", localizer.lastFailure().c_str());

  // With the default screen the readings never reach it: dropped and
  // counted, and tracking goes on (issue 37).
  Localizer screened(s.p_w_anchors, paramsFor(s));
  feed(s, screened);
  EXPECT_EQ(screened.reinitializations(), 0u) << screened.lastFailure();
  EXPECT_EQ(screened.inputDropped()[InputDrop::kBeyondFullScale], 160u);  // 0.2 s at 800 Hz
  EXPECT_TRUE(screened.tracking());
}

TEST(Localizer, EkfBaselineTracksAfterTheSameInitialization) {
  sim::ScenarioParams sp;
  sp.duration_s = 40.0;
  sp.seed = 3;
  const sim::Scenario s = sim::simulateScenario(sp);
  LocalizerParams p = paramsFor(s);
  setEstimatorByName(p, "ekf");
  ASSERT_EQ(p.estimator, LocalizerParams::Estimator::kEkf);
  Localizer localizer(s.p_w_anchors, p);
  const FeedResult run = feed(s, localizer);
  ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
  EXPECT_EQ(localizer.reinitializations(), 0u) << localizer.lastFailure();
  EXPECT_GT(run.tracked_updates, 400);
  // Measured 0.52 m (without the height band in the filter it diverged: 4 m).
  EXPECT_LT(run.mean_error_m, 1.0);
  std::vector<TimedPose> filtered;
  localizer.drainSmoothed(filtered, true);
  EXPECT_GT(filtered.size(), 400u);
  for (std::size_t k = 1; k < filtered.size(); ++k) ASSERT_GE(filtered[k].t_ns, filtered[k - 1].t_ns);
  const auto cov = localizer.latestPoseCovariance();
  ASSERT_TRUE(cov.has_value());
  EXPECT_GT(cov->diagonal().tail<3>().minCoeff(), 0.0);
  EXPECT_LT(cov->diagonal().tail<3>().maxCoeff(), 1.0);
}

TEST(Localizer, SlidingWindowTracksAfterTheSameInitialization) {
  sim::ScenarioParams sp;
  sp.duration_s = 30.0;
  sp.seed = 3;
  const sim::Scenario s = sim::simulateScenario(sp);
  LocalizerParams p = paramsFor(s);
  setEstimatorByName(p, "sliding-window");
  p.sliding_window.window_s = 2.0;
  Localizer localizer(s.p_w_anchors, p);
  const FeedResult run = feed(s, localizer);
  ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
  EXPECT_EQ(localizer.reinitializations(), 0u) << localizer.lastFailure();
  EXPECT_GT(run.tracked_updates, 200);
  EXPECT_LT(run.mean_error_m, 1.0);
  ASSERT_TRUE(localizer.latestPoseCovariance().has_value());
}

/// The time in a failure reason ("... at t=27.950 s ..."), or -1.
double failureTime(const std::string& why) {
  const auto at = why.find("at t=");
  return at == std::string::npos ? -1.0 : std::stod(why.substr(at + 5));
}

// A filter that gates most of its measurements but accepts one group in
// three breaks every run of rejections in a row (max_consecutive_rejections:
// 40); the windowed share catches it within a window. Here 2 of every 3
// ranges in [25, 33) s carry +6 m (beyond every gate).
TEST(Localizer, MostlyRejectedUpdatesReinitializeDespiteLuckyAcceptances) {
  sim::ScenarioParams sp;
  sp.duration_s = 40.0;
  sp.seed = 3;
  sim::Scenario s = sim::simulateScenario(sp);
  const std::int64_t t0_ns = s.imu.front().t_ns;
  const std::int64_t bad_from_ns = t0_ns + 25'000'000'000, bad_to_ns = t0_ns + 33'000'000'000;
  int k = 0;
  for (RangeSample& r : s.ranges) {
    if (r.t_ns >= bad_from_ns && r.t_ns < bad_to_ns && (k++ % 3) != 0) r.range_m += 6.0;
  }
  auto run = [&](int window) {
    LocalizerParams p = paramsFor(s);
    setEstimatorByName(p, "ekf");
    p.rejection_window = window;
    auto localizer = std::make_unique<Localizer>(s.p_w_anchors, p);
    feed(s, *localizer);
    return localizer;
  };
  const double t_bad_s = static_cast<double>(bad_from_ns) * 1e-9;
  const auto without = run(0);
  // Without the window the run of rejections in a row never reaches 40
  // while the lucky third arrives (measured: no failure before 39.5 s).
  if (without->reinitializations() > 0) {
    EXPECT_GT(failureTime(without->lastFailure()), t_bad_s + 8.0) << without->lastFailure();
  }
  const auto with = run(100);
  ASSERT_GE(with->reinitializations(), 1u);
  EXPECT_NE(with->lastFailure().find("of the last 100 updates"), std::string::npos) << with->lastFailure();
  // 100 updates at ~25 per second: measured 2.95 s after the first bad range.
  EXPECT_LT(failureTime(with->lastFailure()), t_bad_s + 8.0) << with->lastFailure();
  std::printf("without the window: %s; with it: %s\n", without->lastFailure().c_str(), with->lastFailure().c_str());
}

TEST(Localizer, RejectionWindowParametersAreValidated) {
  LocalizerParams p;
  p.rejection_window = -1;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p.rejection_window = 0;  // off
  EXPECT_NO_THROW(p.validate());
  p.rejection_window = 100;
  p.max_rejection_share = 1.0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

TEST(Localizer, NamesTheSmoothers) {
  EXPECT_EQ(smootherMethodFromName("d-isam2"), SmootherParams::Method::kDamped);
  EXPECT_EQ(smootherMethodFromName("isam2"), SmootherParams::Method::kGaussNewton);
  EXPECT_EQ(smootherMethodFromName("dogleg"), SmootherParams::Method::kDogleg);
  EXPECT_STREQ(smootherMethodName(SmootherParams::Method::kDamped), "d-isam2");
  EXPECT_THROW(smootherMethodFromName("gtsam"), std::invalid_argument);
  LocalizerParams named;
  setEstimatorByName(named, "isam2");
  EXPECT_EQ(named.estimator, LocalizerParams::Estimator::kSmoother);
  EXPECT_EQ(named.smoother.method, SmootherParams::Method::kGaussNewton);
  setEstimatorByName(named, "sliding-window");
  EXPECT_EQ(named.estimator, LocalizerParams::Estimator::kSlidingWindow);
  EXPECT_THROW(setEstimatorByName(named, "kalman"), std::invalid_argument);
  LocalizerParams bad;
  bad.max_speed_m_s = 0.0;
  EXPECT_THROW(Localizer({Vec3::Zero()}, bad), std::invalid_argument);
}

}  // namespace
}  // namespace rilo

namespace rilo {
namespace {

// Architecture, "poor vertical geometry": anchors 2.0-2.8 m up, the tag at
// ~1.35 m and mostly NLOS (too long) ranges pull the height down. The
// deployment's height band must keep tracked states near a wearer's height.
// The pull is strongest when flagged ranges are modelled with the mixture
// (every small excess pulled to zero); the default NLOS component pulls much
// less, and the band must then not cost much.
TEST(Localizer, HeightBandHoldsTheTrackedHeightUnderNlos) {
  sim::OfficeScenarioParams op;
  op.seed = 2;
  op.duration_s = 40.0;
  const sim::Scenario s = sim::simulateOfficeScenario(op);
  auto vertical_error = [&](bool band_on, bool flagged_component) {
    LocalizerParams p = paramsFor(s);
    p.height_band.min_height_m = 1.0;
    p.height_band.max_height_m = 1.8;
    p.track_height_band = band_on;
    p.graph.range_noise.flagged_nlos_component = flagged_component;
    Localizer localizer(s.p_w_anchors, p);
    EXPECT_TRUE(localizer.heightBandNote().empty()) << localizer.heightBandNote();
    const FeedResult run = feed(s, localizer);
    EXPECT_GT(run.tracked_updates, 100);
    return run.tracked_updates > 0 ? run.mean_abs_height_error_m : 1e9;
  };
  const double with_band = vertical_error(true, false);
  const double without = vertical_error(false, false);
  const double component_with_band = vertical_error(true, true);
  const double component_without = vertical_error(false, true);
  std::printf("mean vertical error, flagged ranges as the mixture: %.3f m with the band, %.3f m without; "
              "as the NLOS component: %.3f / %.3f m\n", with_band, without, component_with_band, component_without);
  EXPECT_LT(with_band, 0.45);
  EXPECT_LT(with_band, 0.8 * without);
  EXPECT_LT(component_with_band, 0.45);
  EXPECT_LT(component_with_band, without) << "the component pulls less than the mixture";
}

// Two-way ranging from anchors at similar heights leaves the height weak:
// the office sim's NLOS excess moves it across the height band over tens of
// seconds. The loose default vertical speed prior ("auto",
// kTwoWayVerticalSpeedSigmaMs) lets the many states of a walk on one floor
// hold it (rilo replay figures in localizer.h). Measured, seeds 1-3: mean
// vertical error 0.264 / 0.095 / 0.193 m against 0.337 / 0.165 / 0.327
// without, 3D 0.336 / 0.168 / 0.257 against 0.407 / 0.225 / 0.369.
TEST(Localizer, DefaultVerticalSpeedPriorSteadiesTheHeightOnTwoWayRanges) {
  double with_prior = 0.0, without = 0.0, error_with = 0.0, error_without = 0.0;
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    sim::OfficeScenarioParams op;
    op.seed = seed;
    op.duration_s = 60.0;
    const sim::Scenario s = sim::simulateOfficeScenario(op);
    auto run = [&](std::optional<double> sigma) {
      LocalizerParams p = paramsFor(s);
      p.vertical_speed_sigma_m_s = sigma;
      Localizer localizer(s.p_w_anchors, p);
      const FeedResult fed = feed(s, localizer);
      EXPECT_GT(fed.tracked_updates, 400) << "seed " << seed;
      EXPECT_EQ(localizer.trackingVerticalSpeedSigma(), sigma.value_or(kTwoWayVerticalSpeedSigmaMs));
      return fed;
    };
    const FeedResult on = run(std::nullopt), off = run(0.0);
    std::printf("seed %llu: mean vertical error %.3f m with the default prior, %.3f m without; 3D %.3f / %.3f m\n",
                static_cast<unsigned long long>(seed), on.mean_abs_height_error_m, off.mean_abs_height_error_m,
                on.mean_error_m, off.mean_error_m);
    with_prior += on.mean_abs_height_error_m;
    without += off.mean_abs_height_error_m;
    error_with += on.mean_error_m;
    error_without += off.mean_error_m;
  }
  EXPECT_LT(with_prior, 0.9 * without);
  EXPECT_LT(error_with, 0.9 * error_without);
}

/// The Lissajous walk with a sit-down: the body drops `drop_m` over
/// `duration_s` from `sit_s` and rises again from `stand_s` (quintic
/// smoothstep, so position, velocity and acceleration stay exact and smooth).
class SitDownWalk final : public sim::Trajectory {
 public:
  SitDownWalk(double sit_s, double stand_s, double drop_m, double duration_s)
      : sit_s_(sit_s), stand_s_(stand_s), drop_m_(drop_m), duration_s_(duration_s) {}
  sim::KinematicState at(double t_s) const override {
    sim::KinematicState k = walk_.at(t_s);
    const Vec3 down = step(t_s - sit_s_), up = step(t_s - stand_s_);
    k.T_w_b.p.z() -= drop_m_ * (down[0] - up[0]);
    k.v_w.z() -= drop_m_ * (down[1] - up[1]);
    k.a_w.z() -= drop_m_ * (down[2] - up[2]);
    return k;
  }
  /// Smoothstep 0 -> 1 over duration_s_ from 0, with its first two derivatives in time.
  Vec3 step(double t) const {
    const double u = std::clamp(t / duration_s_, 0.0, 1.0), T = duration_s_;
    if (u <= 0.0 || u >= 1.0) return Vec3(u, 0.0, 0.0);
    return Vec3(u * u * u * (10.0 - 15.0 * u + 6.0 * u * u), 30.0 * u * u * (1.0 - u) * (1.0 - u) / T,
                60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / (T * T));
  }

 private:
  sim::LissajousWalk walk_;
  double sit_s_, stand_s_, drop_m_, duration_s_;
};

// The sit-down's velocity and acceleration are the derivatives of its
// position (central differences), so its IMU samples are exact; and the
// simulator refuses a missing trajectory or anchor layout.
TEST(SitDownWalk, DerivativesAreConsistentAndTheSimulatorChecksItsInput) {
  const SitDownWalk walk(30.0, 45.0, 0.3, 1.2);
  const double h = 1e-4;
  for (const double t : {29.0, 30.1, 30.6, 31.1, 45.3, 46.0}) {
    const sim::KinematicState k = walk.at(t), before = walk.at(t - h), after = walk.at(t + h);
    EXPECT_NEAR((after.T_w_b.p.z() - before.T_w_b.p.z()) / (2 * h), k.v_w.z(), 1e-6) << "t " << t;
    EXPECT_NEAR((after.v_w.z() - before.v_w.z()) / (2 * h), k.a_w.z(), 1e-5) << "t " << t;
  }
  EXPECT_NEAR(walk.at(40.0).T_w_b.p.z() - sim::LissajousWalk().at(40.0).T_w_b.p.z(), -0.3, 1e-12);
  EXPECT_NEAR(walk.at(50.0).T_w_b.p.z() - sim::LissajousWalk().at(50.0).T_w_b.p.z(), 0.0, 1e-12);
  sim::ScenarioParams sp;
  sp.duration_s = 1.0;
  EXPECT_THROW(sim::simulateScenario(sp, nullptr, sim::defaultOfficeAnchors()), std::invalid_argument);
  EXPECT_THROW(sim::simulateScenario(sp, std::make_shared<SitDownWalk>(walk), {}), std::invalid_argument);
}

// The loose default vertical speed prior holds a walker's height only where
// the ranges let it drift slowly; a sit-down the accelerometer sees stays in
// the estimate. Anchors at similar heights (2.3-2.7 m, the case the prior is
// for): the 0.3 m drop in 1.2 s is carried by the IMU, not by the ranges.
TEST(Localizer, DefaultVerticalSpeedPriorFollowsASitDown) {
  sim::ScenarioParams sp;
  sp.duration_s = 60.0;
  sp.seed = 4;
  std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  const double heights[] = {2.6, 2.3, 2.5, 2.4, 2.7, 2.35, 2.55, 2.45};
  for (std::size_t a = 0; a < anchors.size(); ++a) anchors[a].z() = heights[a];
  constexpr double kSitS = 30.0, kStandS = 45.0, kDropM = 0.3;
  const sim::Scenario s =
      sim::simulateScenario(sp, std::make_shared<SitDownWalk>(kSitS, kStandS, kDropM, 1.2), anchors);
  ASSERT_NEAR(s.truthAt(s.t0_ns + 40'000'000'000).T_w_b.p.z() - s.truthAt(s.t0_ns + 20'000'000'000).T_w_b.p.z(),
              -kDropM, 0.11) << "the walk's own bob is 0.05 m";
  struct Phase {  ///< sums over the tracked estimates of one phase
    double abs_dz = 0.0, z = 0.0;
    int n = 0;
    double meanAbsDz() const { return abs_dz / std::max(1, n); }
    double meanZ() const { return z / std::max(1, n); }
  };
  struct Phases {
    Phase standing, seated;
    double drop() const { return seated.meanZ() - standing.meanZ(); }  ///< estimated height change into the seat, m
  };
  auto run = [&](std::optional<double> sigma) {
    LocalizerParams p = paramsFor(s);
    p.vertical_speed_sigma_m_s = sigma;
    p.track_height_band = false;  // the seated tag (0.98 m) is near the band's floor: judge the prior alone
    Localizer localizer(s.p_w_anchors, p);
    Phases out;
    feed(s, localizer, -1, -1, [&](const StateEstimate& e) {
      const double t = 1e-9 * static_cast<double>(e.t_ns - s.t0_ns);
      Phase* phase = t > 20.0 && t < kSitS ? &out.standing : t > kSitS + 2.0 && t < kStandS ? &out.seated : nullptr;
      if (!phase) return;
      phase->abs_dz += std::abs(e.T_w_b.p.z() - s.truthAt(e.t_ns).T_w_b.p.z());
      phase->z += e.T_w_b.p.z();
      ++phase->n;
    });
    EXPECT_EQ(localizer.reinitializations(), 0u) << localizer.lastFailure();
    EXPECT_GT(out.standing.n, 100);
    EXPECT_GT(out.seated.n, 100);
    return out;
  };
  const Phases with_prior = run(std::nullopt), without = run(0.0);
  std::printf("mean |height error| standing / seated: %.3f / %.3f m with the default prior, %.3f / %.3f m without; "
              "estimated drop %.3f / %.3f m (truth %.2f)\n", with_prior.standing.meanAbsDz(),
              with_prior.seated.meanAbsDz(), without.standing.meanAbsDz(), without.seated.meanAbsDz(), with_prior.drop(),
              without.drop(), kDropM);
  // Measured: seated 0.042 m with the default, 0.040 without; a stiff prior
  // lags the seat (0.05 m/s, TDoA's default: 0.132 m; 0.02 m/s: 0.124 m).
  EXPECT_LT(with_prior.seated.meanAbsDz(), 0.08);
  EXPECT_LT(with_prior.seated.meanAbsDz(), without.seated.meanAbsDz() + 0.03);
  EXPECT_LT(with_prior.standing.meanAbsDz(), without.standing.meanAbsDz() + 0.03);
  // The estimated drop (0.22 m; 0.18 m without the prior) carries the
  // standing phase's own height error too, hence the loose bound.
  EXPECT_LT(with_prior.drop(), -0.5 * kDropM);
}

// The receiver's NLOS flag (power gap, range_model.h) with the site's
// excess of flagged ranges estimated on line (FlaggedExcessParams). With the
// mixture: on the office sim (80 % NLOS, every anchor overhead) the excess
// is positive, is taken off the flagged ranges, and lowers the error
// against the same run without the estimate (measured, default plan, 60 s,
// seeds 1-4: 0.42/0.46/0.34/0.52 m without, 0.35/0.37/0.32/0.46 m with;
// the height bias -0.35/-0.35/-0.25/-0.15 -> -0.25/-0.28/-0.05/-0.03 m).
// With no NLOS excess (severity 0: walls attenuate, nothing is delayed) the
// estimate stays 0, and the NLOS component (the default) then shortens no
// flagged range, where its own mode (no estimate) would shorten every one.
TEST(Localizer, EstimatesTheExcessOfFlaggedRangesAndTakesItOff) {
  auto run = [](double severity, double quantile, bool component, double* excess_m, double* dz_m) {
    sim::OfficeScenarioParams op;
    op.seed = 1;
    op.duration_s = 60.0;
    op.channel.nlos_severity = severity;
    const sim::Scenario s = sim::simulateOfficeScenario(op);
    LocalizerParams p = paramsFor(s);
    // The height shows the flagged ranges' pull only without the hold and
    // lever that now keep it near the band's middle (issue 36).
    p.height_band.hold_sigma_m = 0.0;
    p.height_band.range_lever = false;
    p.flagged_excess.quantile = quantile;
    p.graph.range_noise.flagged_nlos_component = component;
    Localizer localizer(s.p_w_anchors, p);
    const FeedResult fed = feed(s, localizer);
    EXPECT_GT(fed.tracked_updates, 100);
    *dz_m = fed.mean_height_error_m;
    *excess_m = localizer.flaggedExcess();
    return fed.tracked_updates > 0 ? fed.mean_error_m : 1e9;
  };
  double excess = -1.0, unused = 0.0, dz_with = 0.0, dz_without = 0.0, dz_clear = 0.0, dz_mode = 0.0;
  const double with = run(1.0, FlaggedExcessParams().quantile, false, &excess, &dz_with);
  const double without = run(1.0, 0.0, false, &unused, &dz_without);
  std::printf("mixture: flagged excess %.3f m; mean error %.3f m (height %+.3f) with the estimate, %.3f m (%+.3f) without\n",
              excess, with, dz_with, without, dz_without);
  EXPECT_GT(excess, 0.03);
  EXPECT_LE(excess, FlaggedExcessParams().max_m);
  EXPECT_EQ(unused, 0.0) << "quantile 0: off";
  EXPECT_LT(with, without);
  EXPECT_LT(std::abs(dz_with), std::abs(dz_without)) << "the overhead anchors' downward pull shrinks";
  double excess_clear = -1.0;
  const double clear = run(0.0, FlaggedExcessParams().quantile, true, &excess_clear, &dz_clear);
  const double clear_mode = run(0.0, 0.0, true, &unused, &dz_mode);
  std::printf("severity 0, NLOS component: excess %.3f m, mean error %.3f m (height %+.3f) with the estimate, "
              "%.3f m (%+.3f) at the component's mode\n", excess_clear, clear, dz_clear, clear_mode, dz_mode);
  EXPECT_LT(excess_clear, 0.03) << "no delay, no excess";
  EXPECT_LT(clear, 0.7 * clear_mode) << "no flagged range shortened for nothing";
}

// Without the receiver's first-path power (other modules, other firmware),
// the RX level's deficit below the LOS envelope learnt on line stands in for
// the gap (rx_level_envelope.h): on the office sim without its fp_power_dbm
// column the error and the height bias are lower with it than without, and
// where the receiver reports the first-path power the envelope is not used.
TEST(Localizer, RxLevelStandsInForAMissingFirstPathPower) {
  const auto [with_fp, s] = officeWithAndWithoutFirstPath(1);
  double gap_on_db = 0.0, configured_gap_db = 0.0;
  auto run = [&](const sim::Scenario& sc, bool indicator, bool* fitted) {
    LocalizerParams p = paramsFor(sc);
    p.height_band.hold_sigma_m = 0.0;  // as above: the height shows the indicator's effect without the hold
    p.height_band.range_lever = false;
    p.rx_level_envelope.enabled = indicator;
    Localizer localizer(sc.p_w_anchors, p);
    const FeedResult fed = feed(sc, localizer);
    EXPECT_GT(fed.tracked_updates, 100);
    *fitted = localizer.rxLevelEnvelope().fitted();
    gap_on_db = localizer.nlosGapDb();
    configured_gap_db = p.graph.range_noise.nlos_power_gap_db;
    return fed;
  };
  bool fitted_on = false, fitted_off = true, fitted_fp = true;
  const FeedResult on = run(s, true, &fitted_on);
  // The deficits sit on the gap scale from the calibration's LOS reference
  // up: it learnt where below the envelope the excess begins, on this
  // office below the configured 6 dB (a LOS-majority hall may take it past
  // that, los_gap_calibration.h) and above its reference.
  const double learnt_gap_db = gap_on_db;
  EXPECT_LT(learnt_gap_db, configured_gap_db);
  const FeedResult off = run(s, false, &fitted_off);
  const FeedResult fp = run(with_fp, true, &fitted_fp);
  std::printf("no first-path power: mean error %.3f m (height %+.3f) with the RX-level indicator (flag at %.1f dB on "
              "the gap scale), %.3f m (%+.3f) without; with the first-path power %.3f m (%+.3f)\n", on.mean_error_m,
              on.mean_height_error_m, learnt_gap_db, off.mean_error_m, off.mean_height_error_m, fp.mean_error_m,
              fp.mean_height_error_m);
  EXPECT_TRUE(fitted_on);
  EXPECT_FALSE(fitted_off) << "disabled: nothing learnt";
  EXPECT_FALSE(fitted_fp) << "the receiver's own indicator is used where it is reported";
  EXPECT_LT(on.mean_error_m, off.mean_error_m);
  EXPECT_LT(std::abs(on.mean_height_error_m), std::abs(off.mean_height_error_m));
}

// Without the receiver's first-path power, an anchor whose last two ranges
// the mixture took as NLOS has its next flagged (nlos_memory.h); with the
// power, with the memory off, or with a model that has no NLOS branch to
// judge by, nothing is.
TEST(Localizer, RemembersBlockedAnchorsOnlyWhereTheReceiverGivesNoFirstPathPower) {
  const auto [with_fp, s] = officeWithAndWithoutFirstPath(2);
  auto run = [](const sim::Scenario& sc, const std::function<void(LocalizerParams&)>& tweak, std::uint64_t* flagged) {
    LocalizerParams p = paramsFor(sc);
    tweak(p);
    Localizer localizer(sc.p_w_anchors, p);
    const FeedResult fed = feed(sc, localizer);
    EXPECT_GT(fed.tracked_updates, 100);
    *flagged = localizer.rangesFlaggedByMemory();
    return fed;
  };
  std::uint64_t flagged_on = 0, flagged_off = 1, flagged_fp = 1, flagged_huber = 1;
  const FeedResult on = run(s, [](LocalizerParams&) {}, &flagged_on);
  const FeedResult off = run(s, [](LocalizerParams& p) { p.nlos_memory.window_s = 0.0; }, &flagged_off);
  run(with_fp, [](LocalizerParams&) {}, &flagged_fp);
  run(s, [](LocalizerParams& p) { p.graph.range_loss = "huber"; }, &flagged_huber);
  std::printf("no first-path power: %llu ranges flagged by their anchor's memory, mean error %.3f m (height %+.3f); "
              "memory off %.3f m (%+.3f)\n", static_cast<unsigned long long>(flagged_on), on.mean_error_m,
              on.mean_height_error_m, off.mean_error_m, off.mean_height_error_m);
  EXPECT_GT(flagged_on, 100u) << "a 60 s office walk has blocked anchors";
  EXPECT_EQ(flagged_off, 0u);
  EXPECT_EQ(flagged_fp, 0u) << "the receiver's own indicator is used where it is reported";
  EXPECT_EQ(flagged_huber, 0u) << "no mixture, no decision point";
  EXPECT_LT(on.mean_error_m, off.mean_error_m) << "the flags reach the estimate, and help it here";
}

// A device with two UWB antennas (a recording's tags.csv): each range is
// predicted from the antenna that measured it. The office sim's ranges with
// every other one moved to a second antenna 0.6 m from the first by the true
// geometry (its noise and NLOS excess kept): with the table of antennas the
// error is that of the one-antenna run; with one lever arm for both, half the
// ranges are off by up to 0.6 m.
TEST(Localizer, PredictsEachRangeFromTheAntennaThatMeasuredIt) {
  sim::OfficeScenarioParams op;
  op.seed = 2;
  op.duration_s = 60.0;
  op.p_b_tag = Vec3(0.3, 0.0, 0.1);
  const sim::Scenario one = sim::simulateOfficeScenario(op);
  sim::Scenario two = one;
  const Vec3 p_b_second(-0.3, 0.0, 0.1);
  for (std::size_t k = 1; k < two.ranges.size(); k += 2) {
    RangeSample& r = two.ranges[k];
    const Pose3 T = one.truthAt(r.t_ns).T_w_b;
    const Vec3& a = one.p_w_anchors[r.anchor_id];
    r.range_m += (T.transformFrom(p_b_second) - a).norm() - (T.transformFrom(op.p_b_tag) - a).norm();
    r.tag_id = 1;
  }
  // Mean error from 20 s on, when all three track (their starts differ).
  const std::int64_t from_ns = one.t0_ns + 20'000'000'000;
  auto run = [&](const sim::Scenario& s, std::vector<TagLeverArm> arms) {
    LocalizerParams p = paramsFor(s);  // p_b_tag: the first antenna
    p.graph.tag_lever_arms = std::move(arms);
    Localizer localizer(s.p_w_anchors, p);
    double sum = 0.0;
    int n = 0;
    feed(s, localizer, -1, -1, [&](const StateEstimate& x) {
      if (x.t_ns < from_ns) return;
      sum += (x.T_w_b.p - s.truthAt(x.t_ns).T_w_b.p).norm();
      ++n;
    });
    EXPECT_GT(n, 100);
    return n > 0 ? sum / n : std::numeric_limits<double>::infinity();
  };
  const double single_antenna = run(one, {});
  const double with_table = run(two, {{0, op.p_b_tag}, {1, p_b_second}});
  const double one_arm_for_both = run(two, {});
  std::printf("two antennas: mean error after 20 s %.3f m with their lever arms, %.3f m with the first's for both; "
              "one antenna %.3f m\n", with_table, one_arm_for_both, single_antenna);
  EXPECT_LT(with_table, single_antenna + 0.05);
  EXPECT_LT(with_table, one_arm_for_both - 0.1);

  LocalizerParams bad = paramsFor(one);
  bad.graph.tag_lever_arms = {{1, p_b_second}, {1, op.p_b_tag}};
  EXPECT_THROW(Localizer(one.p_w_anchors, bad), std::invalid_argument) << "a tag listed twice";
}

// While the full state waits for motion, a position-only fix of the newest
// ranges (Initializer::provisionalFix): on the office sim at 40 Hz the first
// comes within a second of data (0.5 s), each is near the truth for what its
// covariance says (the height from the band: its middle, its spread; nine in
// ten inside the 3D 99.7 % region), none is
// offered while tracking, and the first full state lands within three sigmas
// of the last fix. At 1 Hz none is offered: seconds of ranges hold too few
// for a walker's fix.
TEST(Localizer, PublishesAPositionWhileTheFullStateWaits) {
  sim::OfficeScenarioParams op;
  op.seed = 1;
  op.duration_s = 40.0;
  const sim::Scenario s = sim::simulateOfficeScenario(op);
  LocalizerParams p = paramsFor(s);
  Localizer localizer(s.p_w_anchors, p);
  std::uint64_t last_sequence = 0;
  int fixes = 0, within_3_sigma = 0;
  std::int64_t first_fix_ns = -1;
  std::optional<Localizer::ProvisionalPosition> last_fix;
  bool fix_while_tracking = false;
  std::optional<Vec3> first_tracked_p;
  std::int64_t first_tracked_ns = 0;
  const auto on_estimate = [&](const StateEstimate& x) {
    fix_while_tracking = fix_while_tracking || localizer.provisionalPosition().has_value();
    if (first_tracked_p) return;
    first_tracked_p = x.T_w_b.p;
    first_tracked_ns = x.t_ns;
  };
  const auto on_initializing = [&] {
    const auto fix = localizer.provisionalPosition();
    if (!fix || fix->sequence == last_sequence) return;
    last_sequence = fix->sequence;
    last_fix = fix;
    ++fixes;
    if (first_fix_ns < 0) first_fix_ns = fix->t_ns;
    ASSERT_TRUE(fix->cov_p_w.allFinite());
    EXPECT_NEAR(fix->p_w_b.z(), p.height_band.midZ() - p.graph.p_b_tag.z(), 1e-9) << "the band's middle";
    const Vec3 e = fix->p_w_b - s.truthAt(fix->t_ns).T_w_b.p;
    const double chi2 = e.dot(fix->cov_p_w.inverse() * e);
    within_3_sigma += chi2 <= 14.2 ? 1 : 0;  // chi^2(3) at 99.7 %
  };
  const FeedResult run = feed(s, localizer, -1, -1, on_estimate, on_initializing);
  ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
  EXPECT_FALSE(fix_while_tracking);
  EXPECT_EQ(localizer.initializations(), 1u) << "the fixes are checked up to the first start only";
  ASSERT_TRUE(first_tracked_p.has_value());
  ASSERT_TRUE(last_fix.has_value());
  std::printf("first position after %.2f s of data, %d fixes, %d within 3 sigma, first full state after %.1f s\n",
              static_cast<double>(first_fix_ns - s.imu.front().t_ns) * 1e-9, fixes, within_3_sigma,
              static_cast<double>(run.first_track_ns - s.imu.front().t_ns) * 1e-9);
  EXPECT_LT(static_cast<double>(first_fix_ns - s.imu.front().t_ns) * 1e-9, 1.0);
  EXPECT_GE(fixes, 5);
  // Each anchor's ranges in a fix's window count as one (provisional_fix.cpp):
  // counted as independent, the fixes claimed a third of their error.
  EXPECT_GE(10 * within_3_sigma, 9 * fixes) << "covariances as wide as the errors";
  // The fix ages as the wearer walks on (up to 2 m/s), and the full state
  // starts at the newest data.
  const double age_s = static_cast<double>(first_tracked_ns - last_fix->t_ns) * 1e-9;
  const Mat3 cov_then = last_fix->cov_p_w + Mat3::Identity() * std::pow(2.0 * age_s, 2);
  const Vec3 jump = *first_tracked_p - last_fix->p_w_b;
  std::printf("hand-over after %.2f s: %.2f m from the last fix\n", age_s, jump.norm());
  EXPECT_LE(jump.dot(cov_then.inverse() * jump), 14.2) << "hand-over within three sigmas";

  sim::OfficeScenarioParams sparse = op;
  sparse.range_rate_hz = 1.0;
  const sim::Scenario s1 = sim::simulateOfficeScenario(sparse);
  Localizer at_1hz(s1.p_w_anchors, paramsFor(s1));
  bool any = false;
  feed(s1, at_1hz, -1, -1, {}, [&] { any = any || at_1hz.provisionalPosition().has_value(); });
  EXPECT_FALSE(any) << "no fix from seconds of 1 Hz ranging";
}

// LocalizerParams::max_outside_anchors_m: only the five anchors at y <= 0
// are surveyed (their box: y in [-5.5, 0]) while the walk goes to y > 0.
// With a limit below how far the walk leaves the box, tracking ends saying
// where the tag was; with the default limit (10 m) it does not. (That
// IMU-only drift through a ranging blackout is not judged: the rilod
// blackout test, RilodFaults.RangingBlackout*, where it went 10.5 m out.)
TEST(Localizer, TrackingFarOutsideTheAnchorsIsAFailure) {
  sim::ScenarioParams sp;
  sp.duration_s = 60.0;
  sim::Scenario s = sim::simulateScenario(sp);
  std::vector<Vec3> kept;
  std::vector<int> new_id(s.p_w_anchors.size(), -1);
  for (std::size_t a = 0; a < s.p_w_anchors.size(); ++a) {
    if (s.p_w_anchors[a].y() > 0.0) continue;
    new_id[a] = static_cast<int>(kept.size());
    kept.push_back(s.p_w_anchors[a]);
  }
  ASSERT_EQ(kept.size(), 5u);
  std::vector<RangeSample> ranges;
  for (RangeSample r : s.ranges) {
    if (new_id[r.anchor_id] < 0) continue;
    r.anchor_id = static_cast<std::uint32_t>(new_id[r.anchor_id]);
    ranges.push_back(r);
  }
  s.ranges = ranges;
  s.p_w_anchors = kept;
  double max_y = -1e9;
  for (double t = 0.0; t < sp.duration_s; t += 0.1) max_y = std::max(max_y, s.truth->at(t).T_w_b.p.y());
  ASSERT_GT(max_y, 2.0) << "the walk must leave the anchors' box by more than the limit below";

  LocalizerParams p = paramsFor(s);
  p.max_outside_anchors_m = 1.0;
  p.init.max_outside_anchors_m = std::numeric_limits<double>::infinity();  // the tracking check alone
  Localizer strict(s.p_w_anchors, p);
  feed(s, strict);
  EXPECT_GE(strict.reinitializations(), 1u);
  EXPECT_NE(strict.lastFailure().find("outside the anchors' area"), std::string::npos) << strict.lastFailure();
  EXPECT_NE(strict.lastFailure().find("(limit 1.0)"), std::string::npos) << strict.lastFailure();

  // The default limit never ends tracking here. (Five anchors on one side
  // and a walk 3 m beyond them are a hard geometry: since the height hold
  // and range lever of issue 36 the tracker loses it at 42.6 s, 32 % of the
  // ranges short of its estimate, where it held on at 0.82 m before; the
  // range check, not the area limit, ends it.)
  Localizer lenient(s.p_w_anchors, paramsFor(s));
  feed(s, lenient);
  EXPECT_GE(lenient.initializations(), 1u) << lenient.initStatus().message;
  EXPECT_EQ(lenient.lastFailure().find("outside the anchors' area"), std::string::npos) << lenient.lastFailure();

  p.max_outside_anchors_m = 0.0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p.max_outside_anchors_m = std::numeric_limits<double>::infinity();
  EXPECT_NO_THROW(p.validate()) << "+inf: off";
}

TEST(LocalizerParams, TheTdoaStateWindowMustFitBelowTheLongestStateInterval) {
  LocalizerParams p;
  EXPECT_NO_THROW(p.validate());
  p.with_tdoa.state_window_ns = 0;  // the graph's window
  EXPECT_NO_THROW(p.validate());
  p.with_tdoa.state_window_ns = p.graph.max_state_interval_ns;  // a state would never close
  try {
    p.validate();
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("with_tdoa.state_window_ns"), std::string::npos) << e.what();
  }
  p.with_tdoa.state_window_ns = -1;
  EXPECT_THROW(p.validate(), std::invalid_argument);
}

TEST(Localizer, DropsAHeightBandThatDoesNotFitTheAnchors) {
  sim::ScenarioParams sp;
  sp.duration_s = 2.0;
  const sim::Scenario s = sim::simulateScenario(sp);
  std::vector<Vec3> anchors = s.p_w_anchors;
  for (Vec3& a : anchors) a.z() -= 10.0;  // a frame whose floor is nowhere near z = 0
  Localizer localizer(anchors, paramsFor(s));
  EXPECT_FALSE(localizer.params().height_band.enabled);
  EXPECT_FALSE(localizer.params().graph.height_band.enabled);
  EXPECT_FALSE(localizer.params().init.height_band.enabled);
  EXPECT_NE(localizer.heightBandNote().find("height band off"), std::string::npos);
}

}  // namespace
}  // namespace rilo
