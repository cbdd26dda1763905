// Per-link measurement sigmas (measurement_noise.h) and their wiring into the
// graph stream and the EKF estimator: off changes nothing; the residuals fed
// measure the link, not the state; on a tracked TDoA walk a pair whose noise
// doubles gets a larger sigma on its new factors, an NLOS burst barely moves
// a pair, and the smoother's increments stay one consistent graph.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <stdexcept>

#include "estimation/assembly/measurement_noise.h"
#include "estimation/factors/tdoa_factor.h"
#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/tracking/ekf_estimator.h"
#include "estimation/tracking/localizer.h"
#include "estimation/tracking/range_imu_estimator.h"
#include "sim/office_scenario.h"
#include "sim/office_tdoa.h"
#include "support/smoother_graphs.h"

namespace rilo {
namespace {

RangeImuGraphParams geometryParams() {
  RangeImuGraphParams g;
  g.p_b_tag = Vec3(0.05, 0.0, 0.1);
  g.p_b_ultrasonic = Vec3(0.0, 0.03, 0.14);
  g.p_w_ultrasonic = {Vec3(2.0, 2.0, 3.0), Vec3(6.0, 2.0, 3.0), Vec3(2.0, 6.0, 3.0), Vec3(6.0, 6.0, 3.0)};
  g.range_noise.sigma_m = 0.12;
  g.tdoa_sigma_m = 0.15;
  g.ultrasonic_sigma_m = 0.02;
  return g;
}

std::vector<Vec3> anchors() {
  return {Vec3(0, 0, 2.5), Vec3(8, 0, 0.5), Vec3(8, 8, 2.5), Vec3(0, 8, 0.5)};
}

const DynamicCovariance& covarianceOf(const MeasurementNoise& noise) {
  if (noise.covariance() == nullptr) throw std::logic_error("dynamic covariance is off");
  return *noise.covariance();
}

/// On, for TDoA and (unlike the default) ultrasonic beacons too.
DynamicCovarianceOptions on() {
  DynamicCovarianceOptions o;
  o.enabled = true;
  o.ultrasonic = true;
  return o;
}

TEST(MeasurementNoise, OffGivesTheConfiguredSigmaOfEachKindAndIgnoresResiduals) {
  MeasurementNoise noise(anchors(), geometryParams(), DynamicCovarianceOptions());
  EXPECT_FALSE(noise.dynamic());
  EXPECT_EQ(noise.covariance(), nullptr);
  const Measurement r{Measurement::Kind::kRange, 0, 1, 0, 5.0};
  const Measurement d{Measurement::Kind::kTdoa, 0, 0, 2, 1.0};
  const Measurement u{Measurement::Kind::kUltrasonic, 0, 3, 0, 2.0};
  for (int k = 0; k < 100; ++k) {
    noise.noteInnovation(d, 3.0, 0.0);
    noise.notePrediction(1, u.t_ns, u, Pose3(), Vec3::Zero());
    noise.notePostFit(1, Pose3(), Vec3::Zero());
  }
  EXPECT_EQ(noise.sigma(r), 0.12);
  EXPECT_EQ(noise.sigma(d), 0.15);
  EXPECT_EQ(noise.sigma(u), 0.02);
  EXPECT_EQ(noise.residualsFed(), 0u);
  EXPECT_EQ(noise.pending(), 0u);
}

TEST(MeasurementNoise, NominalLevelsAreTheGraphSigmasAndTheBoundsWidenToThem) {
  RangeImuGraphParams g = geometryParams();
  g.ultrasonic_sigma_m = 0.001;  // below the default lower bound (5 mm)
  g.tdoa_sigma_m = 3.0;          // above the default upper bound (2 m)
  const DynamicCovarianceParams p = dynamicCovarianceParamsFor(g, DynamicCovarianceParams());
  EXPECT_EQ(p.range.nominal_sigma_m, 0.12);
  EXPECT_EQ(p.ultrasonic.nominal_sigma_m, 0.001);
  EXPECT_EQ(p.ultrasonic.sigma_min_m, 0.001);
  EXPECT_EQ(p.tdoa.sigma_max_m, 3.0);
  EXPECT_NO_THROW(p.validate());
  DynamicCovarianceOptions bad = on();
  bad.max_pending = 0;
  EXPECT_THROW(MeasurementNoise(anchors(), g, bad), std::invalid_argument);
}

TEST(MeasurementNoise, KeysFollowTheLinkOfEachKind) {
  EXPECT_EQ(MeasurementNoise::keyOf({Measurement::Kind::kRange, 0, 3, 0, 1.0}), NoiseKey::range(3));
  EXPECT_EQ(MeasurementNoise::keyOf({Measurement::Kind::kTdoa, 0, 5, 2, 1.0}), NoiseKey::tdoa(2, 5));
  EXPECT_EQ(MeasurementNoise::keyOf({Measurement::Kind::kUltrasonic, 0, 9, 0, 1.0}), NoiseKey::ultrasonic(9));
}

TEST(MeasurementNoise, PredictionsAreTheFactorModels) {
  const RangeImuGraphParams g = geometryParams();
  MeasurementNoise noise(anchors(), g, on());
  const Pose3 T(so3::exp(Vec3(0.1, -0.2, 0.7)), Vec3(3.0, 4.0, 1.2));
  const Vec3 p_tag = T.R * g.p_b_tag + T.p;
  const Vec3 p_us = T.R * g.p_b_ultrasonic + T.p;
  EXPECT_NEAR(noise.predict({Measurement::Kind::kRange, 0, 1, 0, 0.0}, T), (p_tag - anchors()[1]).norm(), 1e-12);
  EXPECT_NEAR(noise.predict({Measurement::Kind::kTdoa, 0, 0, 2, 0.0}, T),
              (p_tag - anchors()[2]).norm() - (p_tag - anchors()[0]).norm(), 1e-12);
  Values x;
  x.insert(sym::X(0), T);
  const TdoaFactor f(sym::X(0), anchors()[0], anchors()[2], 0.0, 0.15, g.p_b_tag);
  EXPECT_NEAR(noise.predict({Measurement::Kind::kTdoa, 0, 0, 2, 0.0}, T), f.predictedDifference(x), 1e-12);
  EXPECT_NEAR(noise.predict({Measurement::Kind::kUltrasonic, 0, 3, 0, 0.0}, T), (p_us - g.p_w_ultrasonic[3]).norm(),
              1e-12);
}

// A state holds the measurements of its window (25 ms for TDoA, 50 ms for
// two-way ranges): a later one's residual is taken where the state's velocity
// takes the tag by its time, as its factor predicts it (RangeTimeOffset), so
// the walk is not mistaken for the link's noise.
TEST(MeasurementNoise, AMeasurementAfterItsStateIsJudgedWhereTheVelocityTakesTheTag) {
  const RangeImuGraphParams g = geometryParams();
  const Pose3 T(so3::exp(Vec3(0.0, 0.0, 0.4)), Vec3(3.0, 4.0, 1.2));
  const Vec3 v_w(1.5, 0.5, 0.0);
  const std::int64_t dt_ns = 40'000'000;
  Pose3 T_later = T;
  T_later.p += 0.04 * v_w;
  for (const Measurement::Kind kind : {Measurement::Kind::kTdoa, Measurement::Kind::kUltrasonic}) {
    MeasurementNoise compensated(anchors(), g, on()), exact(anchors(), g, on()), uncompensated(anchors(), g, on());
    Measurement m{kind, 0, kind == Measurement::Kind::kTdoa ? 0u : 3u, 2, 0.0};
    const double miss_m = compensated.predict(m, T_later) - compensated.predict(m, T);
    ASSERT_GT(std::abs(miss_m), 0.03) << "the walk moves the prediction";
    for (std::uint64_t k = 1; k <= 300; ++k) {
      const std::int64_t t_ns = static_cast<std::int64_t>(k) * 100'000'000;
      m.t_ns = t_ns + dt_ns;
      m.value_m = compensated.predict(m, T_later);  // exact at the measurement's time
      compensated.notePrediction(k, t_ns, m, T, v_w);
      compensated.notePostFit(k, T, v_w);
      uncompensated.notePrediction(k, m.t_ns, m, T, v_w);  // as if measured at the state
      uncompensated.notePostFit(k, T, v_w);
      Measurement at_state = m;
      at_state.t_ns = t_ns;
      at_state.value_m = exact.predict(m, T);
      exact.notePrediction(k, t_ns, at_state, T, v_w);
      exact.notePostFit(k, T, v_w);
    }
    EXPECT_NEAR(compensated.sigma(m), exact.sigma(m), 1e-12) << "kind " << static_cast<int>(kind);
    EXPECT_GT(uncompensated.sigma(m), compensated.sigma(m) + 0.5 * std::abs(miss_m)) << "kind " << static_cast<int>(kind);
  }
}

/// The stream's situation, linearized: a predicted position with error
/// N(0, prior_sigma^2 I), measurements of one state with noise `meas_sigma`,
/// the MAP update of the position from both. Returns the dynamic sigma of the
/// ultrasonic beacon 0 after `states` states.
double ultrasonicSigmaFromPredictionAndPostFit(double meas_sigma, double prior_sigma, int states) {
  const RangeImuGraphParams g = geometryParams();
  MeasurementNoise noise(anchors(), g, on());
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Mat3 R = so3::exp(Vec3(0.0, 0.0, 0.4));
  for (int k = 0; k < states; ++k) {
    const Vec3 p_true(3.0 + 0.001 * k, 4.0, 1.2);
    const Vec3 p_pred = p_true + prior_sigma * Vec3(n01(rng), n01(rng), n01(rng));
    // Every beacon pings once; the update is the MAP position from the
    // prediction and the ranges (Gauss-Newton iterated to convergence).
    std::vector<Measurement> ms;
    for (std::uint32_t b = 0; b < 4; ++b) {
      const Vec3 p_us_true = R * g.p_b_ultrasonic + p_true;
      ms.push_back({Measurement::Kind::kUltrasonic, 0, b, 0,
                    (p_us_true - g.p_w_ultrasonic[b]).norm() + meas_sigma * n01(rng)});
      noise.notePrediction(k, 0, ms.back(), Pose3(R, p_pred), Vec3::Zero());
    }
    Vec3 p_post = p_pred;
    for (int it = 0; it < 8; ++it) {
      Mat3 info = Mat3::Identity() / (prior_sigma * prior_sigma);
      Vec3 rhs = (p_pred - p_post) / (prior_sigma * prior_sigma);
      for (const Measurement& m : ms) {
        const Vec3 d = R * g.p_b_ultrasonic + p_post - g.p_w_ultrasonic[m.anchor];
        const Vec3 u = d.normalized();
        info += u * u.transpose() / (meas_sigma * meas_sigma);
        rhs += u * (m.value_m - d.norm()) / (meas_sigma * meas_sigma);
      }
      p_post += info.ldlt().solve(rhs);
    }
    noise.notePostFit(k, Pose3(R, p_post), Vec3::Zero());
  }
  EXPECT_EQ(noise.pending(), 0u);
  return covarianceOf(noise).sigma(NoiseKey::ultrasonic(0));
}

TEST(MeasurementNoise, InnovationTimesPostFitResidualMeasuresTheLinkNotThePrediction) {
  // 2 cm ranges after a 3 cm prediction: the innovation alone spreads 3.6 cm
  // (a quarter of its variance is the range's), the post-fit residual alone
  // about 1.3 cm (the state was fitted to it). Their product gives 2 cm.
  EXPECT_NEAR(ultrasonicSigmaFromPredictionAndPostFit(0.02, 0.03, 3000), 0.02, 0.002);
  // A prediction much better than the ranges, and much worse.
  EXPECT_NEAR(ultrasonicSigmaFromPredictionAndPostFit(0.05, 0.005, 3000), 0.05, 0.005);
  EXPECT_NEAR(ultrasonicSigmaFromPredictionAndPostFit(0.02, 0.08, 3000), 0.02, 0.003);
  // The identity is linear: a prediction off by 0.2 m bends 2 m ranges by
  // about 0.01 m, which the product counts as range noise.
  EXPECT_GT(ultrasonicSigmaFromPredictionAndPostFit(0.02, 0.2, 3000), 0.023);
}

TEST(MeasurementNoise, InnovationsWithTheirPredictedVarianceGiveTheLinkSigma) {
  MeasurementNoise noise(anchors(), geometryParams(), on());
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  const Measurement d{Measurement::Kind::kTdoa, 0, 1, 3, 0.0};
  const double sigma = 0.3, hph = 0.04;  // innovation variance 0.09 + 0.04
  for (int k = 0; k < 4000; ++k) noise.noteInnovation(d, std::sqrt(sigma * sigma + hph) * n01(rng), hph);
  EXPECT_NEAR(noise.sigma(d), sigma, 0.04);
  EXPECT_EQ(noise.residualsFed(), 4000u);
}

TEST(MeasurementNoise, TwoWayRangesKeepTheirSigmaUnlessAsked) {
  // Their asymmetric loss models the NLOS tail itself (DynamicCovarianceOptions::range).
  const Measurement r{Measurement::Kind::kRange, 0, 2, 0, 5.0};
  DynamicCovarianceOptions options = on();
  MeasurementNoise noise(anchors(), geometryParams(), options);
  EXPECT_FALSE(noise.dynamicKind(Measurement::Kind::kRange));
  EXPECT_TRUE(noise.dynamicKind(Measurement::Kind::kTdoa));
  for (int k = 0; k < 200; ++k) noise.noteInnovation(r, k % 2 == 0 ? 0.6 : -0.6, 0.0);
  EXPECT_EQ(noise.sigma(r), 0.12);
  EXPECT_EQ(noise.residualsFed(), 0u);
  options.range = true;
  options.ultrasonic = false;
  MeasurementNoise with_ranges(anchors(), geometryParams(), options);
  for (int k = 0; k < 200; ++k) with_ranges.noteInnovation(r, k % 2 == 0 ? 0.6 : -0.6, 0.0);
  EXPECT_NEAR(with_ranges.sigma(r), 0.6, 0.1);
  const Measurement u{Measurement::Kind::kUltrasonic, 0, 1, 0, 2.0};
  with_ranges.notePrediction(3, 0, u, Pose3(), Vec3::Zero());
  EXPECT_EQ(with_ranges.pending(), 0u);
}

TEST(MeasurementNoise, ByDefaultOnlyTdoaPairsGetEstimatedSigmas) {
  // Ranges and ultrasonic ranges have the asymmetric loss, which models their
  // NLOS / reflection tail itself (DynamicCovarianceOptions::ultrasonic).
  DynamicCovarianceOptions options;
  options.enabled = true;
  MeasurementNoise noise(anchors(), geometryParams(), options);
  EXPECT_TRUE(noise.dynamicKind(Measurement::Kind::kTdoa));
  EXPECT_FALSE(noise.dynamicKind(Measurement::Kind::kRange));
  EXPECT_FALSE(noise.dynamicKind(Measurement::Kind::kUltrasonic));
  const Measurement u{Measurement::Kind::kUltrasonic, 0, 1, 0, 2.0};
  for (int k = 0; k < 200; ++k) noise.noteInnovation(u, k % 2 == 0 ? 0.3 : -0.3, 0.0);
  EXPECT_EQ(noise.sigma(u), geometryParams().ultrasonic_sigma_m);
  EXPECT_EQ(noise.residualsFed(), 0u);
}

TEST(MeasurementNoise, PendingNotesOfAnotherStateAreDroppedAndTheBufferIsBounded) {
  DynamicCovarianceOptions o = on();
  o.max_pending = 3;
  MeasurementNoise noise(anchors(), geometryParams(), o);
  const Measurement d{Measurement::Kind::kTdoa, 0, 1, 3, 0.0};
  for (int k = 0; k < 5; ++k) noise.notePrediction(4, 0, d, Pose3(), Vec3::Zero());
  EXPECT_EQ(noise.pending(), 3u);
  EXPECT_EQ(noise.pendingOverflow(), 2u);
  noise.notePostFit(3, Pose3(), Vec3::Zero());  // not the pending state: kept
  EXPECT_EQ(noise.pending(), 3u);
  noise.notePrediction(5, 0, d, Pose3(), Vec3::Zero());  // state 4 never came back: dropped
  EXPECT_EQ(noise.pending(), 1u);
  noise.notePostFit(5, Pose3(), Vec3::Zero());
  EXPECT_EQ(noise.pending(), 0u);
  EXPECT_EQ(noise.residualsFed(), 1u);
}

// ---- On a tracked TDoA walk ----------------------------------------------------

struct TdoaWalk {
  sim::Scenario s;
  std::vector<TdoaSample> tdoa;
  double sigma_m = 0.15;
};

/// Clean hall walk with TDoA (no NLOS, no outliers): every pair LOS-like.
TdoaWalk cleanHallTdoa(double duration_s) {
  sim::OfficeScenarioParams p;
  p.seed = 4;
  p.duration_s = duration_s;
  p.plan = sim::OfficePlanKind::kHall;
  p.channel.nlos_severity = 0.0;
  p.tdoa.enabled = true;
  p.tdoa.outlier_probability = 0.0;
  p.tdoa.nlos_noise_factor = 1.0;  // the hall's obstructed paths are noisier by default
  TdoaWalk w{sim::simulateOfficeScenario(p), {}, p.tdoa.sigma_m};
  sim::OfficeTdoaStream stream(p, sim::makeOfficeSetup(p));
  TdoaSample d;
  sim::TdoaTruth truth;
  while (stream.next(d, truth)) w.tdoa.push_back(d);
  return w;
}

LocalizerParams trackingParams(const TdoaWalk& w) {
  LocalizerParams lp;
  lp.graph.imu = sim::imuParamsOf(w.s.params);
  lp.graph.p_b_tag = w.s.p_b_tag;
  lp.graph.height_band = lp.height_band;
  lp.graph.tdoa_sigma_m = w.sigma_m;
  lp.graph.same_state_window_ns = 25'000'000;
  lp.smoother.lag_s = 3.0;
  lp.stream.dynamic_covariance.enabled = true;
  lp.ekf.dynamic_covariance.enabled = true;
  return lp;
}

/// Starts at the truth 2 s in and feeds everything in time order.
void track(const TdoaWalk& w, TrackingEstimator& e, const std::function<void()>& after_update = {}) {
  const std::int64_t t_start = w.s.t0_ns + 2'000'000'000;
  const sim::KinematicState x0 = w.s.truthAt(t_start);
  e.start(t_start, x0.T_w_b, x0.v_w, ImuBias());
  std::size_t i = 0, k = 0;
  while (w.s.imu[i].t_ns < t_start) ++i;
  while (k < w.tdoa.size() && w.tdoa[k].t_ns <= t_start) ++k;
  while (i < w.s.imu.size() || k < w.tdoa.size()) {
    if (k < w.tdoa.size() && (i >= w.s.imu.size() || w.tdoa[k].t_ns <= w.s.imu[i].t_ns)) {
      e.addTdoa(w.tdoa[k++]);
    } else {
      e.addImu(w.s.imu[i++]);
    }
    if (e.process() > 0 && after_update) after_update();
  }
  e.finish();
  e.process();
}

/// From t_from_s on, pair (a, b)'s rows get extra N(0, 3 sigma^2) noise: its spread doubles.
void doubleNoiseOfPair(TdoaWalk& w, std::uint32_t a, std::uint32_t b, double t_from_s) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> extra(0.0, std::sqrt(3.0) * w.sigma_m);
  for (TdoaSample& d : w.tdoa) {
    const bool pair = (d.anchor_a == a && d.anchor_b == b) || (d.anchor_a == b && d.anchor_b == a);
    if (pair && static_cast<double>(d.t_ns - w.s.t0_ns) * 1e-9 >= t_from_s) d.diff_m += extra(rng);
  }
}

/// Pair (a, b)'s first `rows` rows after t_s measure `excess_m` longer (NLOS on b).
void nlosBurstOnPair(TdoaWalk& w, std::uint32_t a, std::uint32_t b, double t_s, int rows, double excess_m) {
  for (TdoaSample& d : w.tdoa) {
    if (rows > 0 && d.anchor_a == a && d.anchor_b == b && static_cast<double>(d.t_ns - w.s.t0_ns) * 1e-9 >= t_s) {
      d.diff_m += excess_m;
      --rows;
    }
  }
}

/// The anchor pairs of the walk's rows, in the order the rows name them,
/// with their number of rows.
struct Pair {
  std::uint32_t a = 0, b = 0;
  int rows = 0;
  NoiseKey key() const { return NoiseKey::tdoa(a, b); }
};

/// Pairs with at least min_rows rows, the most frequent first.
std::vector<Pair> pairsOf(const TdoaWalk& w, int min_rows = 1) {
  std::vector<Pair> pairs;
  for (const TdoaSample& d : w.tdoa) {
    auto it = std::find_if(pairs.begin(), pairs.end(),
                           [&](const Pair& p) { return p.key() == NoiseKey::tdoa(d.anchor_a, d.anchor_b); });
    if (it == pairs.end()) it = pairs.insert(pairs.end(), Pair{d.anchor_a, d.anchor_b, 0});
    ++it->rows;
  }
  std::stable_sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) { return x.rows > y.rows; });
  while (!pairs.empty() && pairs.back().rows < min_rows) pairs.pop_back();
  return pairs;
}

TEST(DynamicCovarianceWiring, StreamGivesANoisierPairALargerSigmaAndShrugsOffAnNlosBurst) {
  TdoaWalk w = cleanHallTdoa(40.0);
  const std::vector<Pair> pairs = pairsOf(w, 400);  // 10 s of rows or more
  ASSERT_GE(pairs.size(), 6u);
  const NoiseKey noisy = pairs[0].key(), burst = pairs[2].key();
  doubleNoiseOfPair(w, pairs[0].a, pairs[0].b, 10.0);
  nlosBurstOnPair(w, pairs[2].a, pairs[2].b, 25.0, 5, 3.0);
  const LocalizerParams lp = trackingParams(w);
  RangeImuEstimator e(w.s.p_w_anchors, lp.graph, std::make_unique<BayesTreeSmoother>(lp.smoother), lp.stream);
  double burst_sigma_before = 0.0;
  bool burst_seen = false;
  track(w, e, [&] {
    if (!burst_seen && e.latest().t_ns - w.s.t0_ns > 24'900'000'000) {
      burst_sigma_before = covarianceOf(e.stream().measurementNoise()).sigma(burst);
      burst_seen = true;
    }
  });
  const MeasurementNoise& noise = e.stream().measurementNoise();
  ASSERT_TRUE(noise.dynamic());
  const DynamicCovariance& cov = covarianceOf(noise);
  EXPECT_GT(noise.residualsFed(), 3000u);
  EXPECT_EQ(noise.pendingOverflow(), 0u);
  // Clean pairs stay near the simulated 0.15 m (the anchor biases add a little).
  for (const Pair& p : pairs) {
    const NoiseKey k = p.key();
    if (k == noisy || k == burst) continue;
    ASSERT_TRUE(cov.estimated(k));
    EXPECT_GT(cov.sigma(k), 0.10) << k.a << "-" << k.b;
    EXPECT_LT(cov.sigma(k), 0.21) << k.a << "-" << k.b;
  }
  EXPECT_GT(cov.sigma(noisy), 0.25);
  EXPECT_LT(cov.sigma(noisy), 0.40);
  ASSERT_TRUE(burst_seen);
  EXPECT_LT(std::abs(cov.sigma(burst) / burst_sigma_before - 1.0), 0.15);
  // The newest factors of the noisy pair carry its larger sigma.
  const auto* smoother = dynamic_cast<const BayesTreeSmoother*>(&e.smoother());
  ASSERT_NE(smoother, nullptr);
  int noisy_factors = 0;
  for (const FactorPtr& f : smoother->nonlinearFactors()) {
    const auto* t = dynamic_cast<const TdoaFactor*>(f.get());
    if (t == nullptr) continue;
    const bool is_noisy = t->anchorsAreVariables() &&
                          NoiseKey::tdoa(keyIndex(t->anchorAKey()), keyIndex(t->anchorBKey())) == noisy;
    if (!is_noisy) continue;
    ++noisy_factors;
    EXPECT_GT(t->sigma(), 0.22);
  }
  EXPECT_GT(noisy_factors, 20);
}

TEST(DynamicCovarianceWiring, EkfGivesANoisierPairALargerSigma) {
  TdoaWalk w = cleanHallTdoa(40.0);
  const std::vector<Pair> pairs = pairsOf(w, 400);
  ASSERT_GE(pairs.size(), 6u);
  const NoiseKey noisy = pairs[1].key();
  doubleNoiseOfPair(w, pairs[1].a, pairs[1].b, 10.0);
  const LocalizerParams lp = trackingParams(w);
  EkfEstimator e(w.s.p_w_anchors, lp.graph, lp.ekf);
  track(w, e);
  const DynamicCovariance& cov = covarianceOf(e.measurementNoise());
  for (const Pair& p : pairs) {
    const NoiseKey k = p.key();
    if (k == noisy) continue;
    EXPECT_GT(cov.sigma(k), 0.10) << k.a << "-" << k.b;
    EXPECT_LT(cov.sigma(k), 0.21) << k.a << "-" << k.b;
  }
  EXPECT_GT(cov.sigma(noisy), 0.25);
  EXPECT_LT(cov.sigma(noisy), 0.40);
}

TEST(DynamicCovarianceWiring, WarmingUpGivesExactlyTheGraphOfDynamicCovarianceOff) {
  // Same stream, one with dynamic covariance on but no link out of its
  // warm-up (3 s of tracking, about 60 rows a pair, 64 needed): every factor
  // has the configured sigma, so both smoothers end identical.
  TdoaWalk w = cleanHallTdoa(5.0);
  LocalizerParams off = trackingParams(w);
  off.stream.dynamic_covariance.enabled = false;
  LocalizerParams warm = trackingParams(w);
  warm.stream.dynamic_covariance.params.min_samples = DynamicCovariance::kMaxWarmupSamples;
  RangeImuEstimator a(w.s.p_w_anchors, off.graph, std::make_unique<BayesTreeSmoother>(off.smoother), off.stream);
  RangeImuEstimator b(w.s.p_w_anchors, warm.graph, std::make_unique<BayesTreeSmoother>(warm.smoother), warm.stream);
  track(w, a);
  track(w, b);
  const DynamicCovariance& cov = covarianceOf(b.stream().measurementNoise());
  ASSERT_GE(cov.size(), 6);
  EXPECT_GT(b.stream().measurementNoise().residualsFed(), 300u);
  for (const Pair& p : pairsOf(w)) ASSERT_FALSE(cov.estimated(p.key()));
  EXPECT_GT(a.latest().index, 50u);
  EXPECT_EQ(a.latest().index, b.latest().index);
  EXPECT_EQ(a.latest().T_w_b.p, b.latest().T_w_b.p);
  EXPECT_EQ(a.latest().v_w, b.latest().v_w);
}

TEST(DynamicCovarianceWiring, IncrementsWithDynamicSigmasStayOneConsistentGraph) {
  // The tree's solution must equal the dense least-squares solution of all the
  // factors it holds (whatever sigma each got when it was created) after
  // every update: the sigmas change between increments, never inside the graph.
  TdoaWalk w = cleanHallTdoa(12.0);
  const std::vector<Pair> pairs = pairsOf(w);
  doubleNoiseOfPair(w, pairs[0].a, pairs[0].b, 0.0);
  LocalizerParams lp = trackingParams(w);
  lp.graph.tdoa_loss = "gaussian";
  lp.smoother.method = SmootherParams::Method::kGaussNewton;
  lp.smoother.wildfire_threshold = 0.0;
  lp.smoother.lag_s = 1.0;
  lp.stream.dynamic_covariance.params.min_samples = 5;
  lp.stream.dynamic_covariance.params.window_samples = 10.0;  // sigmas move fast
  auto owned = std::make_unique<BayesTreeSmoother>(lp.smoother);
  BayesTreeSmoother& smoother = *owned;
  RangeImuEstimator e(w.s.p_w_anchors, lp.graph, std::move(owned), lp.stream);
  int updates = 0;
  double sigma_min = 1e9, sigma_max = 0.0;
  track(w, e, [&] {
    ++updates;
    if (updates % 10 != 0) return;  // the dense reference is slow
    ASSERT_EQ(smoother.checkInvariants(), "");
    const testing::DeltaComparison c = testing::compareDeltaWithDense(smoother, smoother.nonlinearFactors());
    ASSERT_LT(c.worst, 1e-9 * std::max(c.scale, 1e-2)) << "update " << updates << " at " << c.worst_key;
    for (const FactorPtr& f : smoother.nonlinearFactors()) {
      if (const auto* t = dynamic_cast<const TdoaFactor*>(f.get())) {
        sigma_min = std::min(sigma_min, t->sigma());
        sigma_max = std::max(sigma_max, t->sigma());
      }
    }
  });
  EXPECT_GT(updates, 200);
  EXPECT_GT(sigma_max, 1.5 * sigma_min);  // the factors in the window really had different sigmas
  const Vec3 err = e.latest().T_w_b.p - w.s.truthAt(e.latest().t_ns).T_w_b.p;
  EXPECT_LT(err.head<2>().norm(), 0.3);
}

}  // namespace
}  // namespace rilo
