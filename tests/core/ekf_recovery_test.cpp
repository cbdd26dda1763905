// Error-state EKF: what keeps it from running away on TDoA (issue 7): gate
// recovery of the group update (EkfParams::recovery_gated_share) and the
// unmodelled-acceleration process noise (EkfParams::velocity_noise_density).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "estimation/ekf/error_state_ekf.h"
#include "estimation/tracking/ekf_estimator.h"
#include "support/expect_throws_naming.h"
#include "support/tdoa_row.h"

namespace rilo {
namespace {

using rilo::testing::expectThrowsNaming;

Mat15 diagonalCovariance(double s_theta, double s_p, double s_v, double s_ba, double s_bg) {
  Vec15 s;
  s << Vec3::Constant(s_theta), Vec3::Constant(s_p), Vec3::Constant(s_v), Vec3::Constant(s_ba),
      Vec3::Constant(s_bg);
  return s.cwiseAbs2().asDiagonal();
}

// Eight anchors around a 10 x 8 m room (ids 0..7).
const std::vector<Vec3>& anchors() {
  static const std::vector<Vec3> kAnchors = {Vec3(0, 0, 2.5), Vec3(10, 0, 2.4), Vec3(10, 8, 2.6), Vec3(0, 8, 2.5),
                                             Vec3(5, 0, 0.5), Vec3(10, 4, 0.4), Vec3(5, 8, 0.6), Vec3(0, 4, 0.5)};
  return kAnchors;
}

/// Exact chained rows ids[0]->ids[1]->... at p_w_tag (tag antenna at the body origin).
std::vector<EkfTdoaRow> exactChain(const Vec3& p_w_tag, const std::vector<std::uint32_t>& ids, double sigma_m) {
  std::vector<EkfTdoaRow> rows;
  for (std::size_t k = 0; k + 1 < ids.size(); ++k) {
    EkfTdoaRow r;
    r.anchor_a = ids[k];
    r.anchor_b = ids[k + 1];
    r.p_w_anchor_a = anchors()[r.anchor_a];
    r.p_w_anchor_b = anchors()[r.anchor_b];
    r.diff_m = (p_w_tag - r.p_w_anchor_b).norm() - (p_w_tag - r.p_w_anchor_a).norm();
    r.sigma_m = sigma_m;
    rows.push_back(r);
  }
  return rows;
}

const Vec3 kTruth(5.0, 4.0, 1.2);
const Vec3 kOffset(2.0, 1.5, 0.0);  // where the filter believes it is, relative to the truth

ErrorStateEkf offFilter(const EkfParams& params) {
  ErrorStateEkf ekf(params);
  // 2.5 m off with a 10 cm position sigma: the rows' innovations are far beyond the gate.
  ekf.initialize(0, EkfState(Pose3(Mat3::Identity(), kTruth + kOffset), Vec3::Zero(), ImuBias()),
                 diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001));
  return ekf;
}

// The mechanism of the runaway: a confident filter that is off refuses the
// very rows that would bring it back, for good. Gate recovery applies them once
// the average refused share passes the threshold: here after exactly 7 wholly
// refused groups (1 - (1 - 1/20)^7 = 0.302 > 0.3), and the filter comes back.
TEST(EkfGateRecovery, RefusedRowsAreAppliedOnceTheRefusedShareExceedsTheThreshold) {
  const std::vector<EkfTdoaRow> rows = exactChain(kTruth, {2, 4, 6, 0, 5}, 0.15);
  const int n = static_cast<int>(rows.size());

  EkfParams off;
  off.recovery_gated_share = 1.0;  // off: a share never exceeds 1
  ErrorStateEkf stuck = offFilter(off);
  const EkfState x_stuck = stuck.state();
  for (int k = 0; k < 100; ++k) {
    const EkfGroupResult r = stuck.updateTdoaGroup(rows.data(), n, Vec3::Zero());
    ASSERT_EQ(r.gated, n) << k;
    EXPECT_EQ(r.recovered, 0) << k;
  }
  EXPECT_EQ(stuck.state().local(x_stuck).norm(), 0.0) << "without recovery the filter never comes back";
  EXPECT_NEAR(stuck.gatedShare(), 1.0 - std::pow(0.95, 100), 1e-12);

  ErrorStateEkf ekf = offFilter(EkfParams());
  const double alpha = 1.0 / EkfParams().recovery_window_groups;
  double share = 0.0;
  for (int k = 0; k < 7; ++k) {
    const EkfGroupResult r = ekf.updateTdoaGroup(rows.data(), n, Vec3::Zero());
    EXPECT_EQ(r.gated, n) << k;
    EXPECT_EQ(r.recovered, 0) << k;
    share += alpha * (1.0 - share);
    EXPECT_NEAR(ekf.gatedShare(), share, 1e-12) << k;
  }
  EXPECT_LT((ekf.state().p_w_b - (kTruth + kOffset)).norm(), 1e-12) << "refused groups leave the state alone";
  ASSERT_GT(share, EkfParams().recovery_gated_share);

  const double error_before = (ekf.state().p_w_b - kTruth).norm();
  const EkfGroupResult r = ekf.updateTdoaGroup(rows.data(), n, Vec3::Zero());
  EXPECT_EQ(r.gated, 0);
  EXPECT_EQ(r.recovered, n);
  EXPECT_EQ(r.accepted, n);
  for (int i = 0; i < n; ++i) EXPECT_EQ(r.status[i], UpdateStatus::kAccepted) << i;
  EXPECT_LT((ekf.state().p_w_b - kTruth).norm(), 0.5 * error_before) << "the recovered rows pull the filter back";
  // A recovered group counts as refusing none: the share decays, the gate closes again.
  EXPECT_NEAR(ekf.gatedShare(), share * (1.0 - alpha), 1e-12);
  EXPECT_EQ(ekf.counters().tdoa_recovered, static_cast<std::uint64_t>(n));
  EXPECT_EQ(ekf.counters().tdoa.gated, static_cast<std::uint64_t>(7 * n));

  for (int k = 0; k < 100; ++k) ekf.updateTdoaGroup(rows.data(), n, Vec3::Zero());
  EXPECT_LT((ekf.state().p_w_b - kTruth).norm(), 0.05) << "back on the truth";
  const EkfGroupResult healthy = ekf.updateTdoaGroup(rows.data(), n, Vec3::Zero());
  EXPECT_EQ(healthy.gated, 0);
  EXPECT_EQ(healthy.recovered, 0) << "rows the gate passes are not recovered ones";
  EXPECT_LE(ekf.gatedShare(), EkfParams().recovery_gated_share);
}

TEST(EkfGateRecovery, ConsistentRowsNeverOpenTheGateAndInitializeResetsTheShare) {
  EkfParams params;
  ErrorStateEkf ekf(params);
  ekf.initialize(0, EkfState(Pose3(Mat3::Identity(), kTruth), Vec3::Zero(), ImuBias()),
                 diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001));
  const std::vector<EkfTdoaRow> rows = exactChain(kTruth, {2, 4, 6, 0, 5}, 0.15);
  for (int k = 0; k < 50; ++k) {
    const EkfGroupResult r = ekf.updateTdoaGroup(rows.data(), 4, Vec3::Zero());
    EXPECT_EQ(r.gated, 0) << k;
    EXPECT_EQ(r.recovered, 0) << k;
  }
  EXPECT_EQ(ekf.gatedShare(), 0.0);
  EXPECT_EQ(ekf.counters().tdoa_recovered, 0u);

  // A share built up before a restart does not carry over.
  ErrorStateEkf off = offFilter(params);
  const std::vector<EkfTdoaRow> far = exactChain(kTruth, {2, 4, 6, 0, 5}, 0.15);
  for (int k = 0; k < 5; ++k) off.updateTdoaGroup(far.data(), 4, Vec3::Zero());
  EXPECT_GT(off.gatedShare(), 0.2);
  off.initialize(0, EkfState(Pose3(Mat3::Identity(), kTruth), Vec3::Zero(), ImuBias()),
                 diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001));
  EXPECT_EQ(off.gatedShare(), 0.0);
}

ImuSample standing(std::int64_t t_ns) {
  ImuSample s;
  s.t_ns = t_ns;
  s.gyro_rad_s = Vec3::Zero();
  s.accel_m_s2 = Vec3(0.0, 0.0, 9.81);
  return s;
}

// The unmodelled acceleration is white noise on top of the IMU's: over T
// seconds it adds exactly q^2 T to each velocity variance (velocity does not
// feed back into attitude or bias), and q^2 T^3 / 3, q^2 T^2 / 2 to position
// and position-velocity (the discrete sum approaches them as dt -> 0); the
// state itself is not changed.
TEST(EkfVelocityNoise, AddsWhiteAccelerationVariance) {
  EkfParams with_q;
  with_q.velocity_noise_density = 0.3;
  const double q2 = 0.09;
  ErrorStateEkf a(with_q), b{EkfParams()};
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(1, 2, 1)), Vec3(0.5, 0, 0), ImuBias());
  const Mat15 P0 = diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001);
  a.initialize(0, x0, P0);
  b.initialize(0, x0, P0);
  const double T = 2.0;
  for (std::int64_t t = 0; t <= 2'000'000'000; t += 1'250'000) {  // 800 Hz
    a.propagate(standing(t));
    b.propagate(standing(t));
  }
  ASSERT_EQ(a.t_ns(), 2'000'000'000);
  EXPECT_EQ(a.state().local(b.state()).norm(), 0.0);
  const Mat15 D = a.covariance() - b.covariance();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(D(6 + i, 6 + i), q2 * T, 1e-9 * q2 * T) << i;
    EXPECT_NEAR(D(3 + i, 6 + i), q2 * T * T / 2.0, 1e-3 * q2 * T * T / 2.0) << i;
    EXPECT_NEAR(D(3 + i, 3 + i), q2 * T * T * T / 3.0, 1e-3 * q2 * T * T * T / 3.0) << i;
  }
  // Attitude and biases untouched.
  EXPECT_LE((D.topLeftCorner<3, 3>().cwiseAbs().maxCoeff()), 1e-15);
  EXPECT_LE((D.bottomRightCorner<6, 6>().cwiseAbs().maxCoeff()), 1e-15);
}

TEST(EkfRecoveryParams, InvalidValuesNameTheField) {
  auto with = [](auto set) {
    EkfParams p;
    set(p);
    return p;
  };
  expectThrowsNaming([&] { ErrorStateEkf(with([](EkfParams& p) { p.velocity_noise_density = -0.1; })); },
                     "velocity_noise_density");
  expectThrowsNaming([&] { ErrorStateEkf(with([](EkfParams& p) { p.recovery_gated_share = 0.0; })); },
                     "recovery_gated_share");
  expectThrowsNaming([&] { ErrorStateEkf(with([](EkfParams& p) { p.recovery_window_groups = 0.5; })); },
                     "recovery_window_groups");
}

// The pipeline: rows that gate recovery applied still count as refused for
// the tracking-failure share (UpdateStats::step_accepted), so recovery never
// hides a lost filter from the Localizer's rejection window.
TEST(EkfEstimatorRecovery, RecoveredRowsStillCountAsRefusedSteps) {
  RangeImuGraphParams gp;
  gp.same_state_window_ns = 25'000'000;
  EkfEstimator ekf(anchors(), gp);
  StartCovariance c;
  c.pose = Mat6::Zero();
  c.pose.diagonal() << Vec3::Constant(1e-4), Vec3::Constant(0.01);
  c.velocity = 0.01 * Mat3::Identity();
  c.bias = 1e-6 * Mat6::Identity();
  ekf.start(0, Pose3(Mat3::Identity(), kTruth + kOffset), Vec3::Zero(), ImuBias(), c);
  std::int64_t t = 0;
  int steps = 0, recovered_steps = 0;
  for (int group = 0; group < 60; ++group) {
    const EkfCounters before = ekf.filter().counters();
    // IMU past the window: the previous group closes (its update and its step).
    for (int k = 0; k < 20; ++k, t += 5'000'000) ekf.addImu(standing(t));
    const EkfCounters after = ekf.filter().counters();
    std::vector<UpdateStats> stats;
    ekf.process(&stats);
    if (group > 0) {
      ASSERT_EQ(stats.size(), 1u) << group;
      ++steps;
      const std::uint64_t recovered = after.tdoa_recovered - before.tdoa_recovered;
      const std::uint64_t passed = after.tdoa.accepted - before.tdoa.accepted - recovered;
      // Four rows a group: accepted when at least two passed the gate.
      EXPECT_EQ(stats[0].step_accepted, passed >= 2) << group;
      // Recovered rows count as refused: a group applied by recovery alone is a refused step.
      if (recovered > 0 && !stats[0].step_accepted) ++recovered_steps;
    }
    const std::uint32_t chain[5] = {2, 4, 6, 0, 5};
    for (int k = 0; k < 4; ++k) {
      const double diff_m = (kTruth - anchors()[chain[k + 1]]).norm() - (kTruth - anchors()[chain[k]]).norm();
      ekf.addTdoa(testing::tdoaRow(t + k * 2'000'000, chain[k], chain[k + 1], diff_m));
    }
  }
  EXPECT_EQ(steps, 59);
  EXPECT_GT(recovered_steps, 0) << "the test needs refused steps whose rows gate recovery applied";
  EXPECT_LT((ekf.latest().T_w_b.p - kTruth).norm(), 0.5 * kOffset.norm()) << "and they bring the filter back";
}

}  // namespace
}  // namespace rilo
