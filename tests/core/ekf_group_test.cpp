// Error-state EKF: the joint TDoA group update (group gate, correlated rows,
// iterated re-weighted update) and the IMU-gap process noise.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>

#include "estimation/ekf/error_state_ekf.h"
#include "estimation/noise/huber_loss.h"
#include "support/expect_throws_naming.h"
#include "support/new_counter.h"
#include "support/random_states.h"

namespace rilo {
namespace {

using rilo::testing::expectThrowsNaming;

using testing::randomRotation;
using testing::randomVec;

Mat15 diagonalCovariance(double s_theta, double s_p, double s_v, double s_ba, double s_bg) {
  Vec15 s;
  s << Vec3::Constant(s_theta), Vec3::Constant(s_p), Vec3::Constant(s_v), Vec3::Constant(s_ba),
      Vec3::Constant(s_bg);
  return s.cwiseAbs2().asDiagonal();
}

Mat15 randomCovariance(std::mt19937& rng) {
  Mat15 L = Mat15::Zero();
  for (int r = 0; r < 15; ++r)
    for (int c = 0; c <= r; ++c) L(r, c) = std::normal_distribution<double>(0.0, 0.1)(rng);
  return L * L.transpose() + 1e-3 * Mat15::Identity();
}

// Eight anchors around a 10 x 8 m room (ids 0..7).
Vec3 anchor(std::uint32_t id) {
  static const Vec3 kAnchors[8] = {Vec3(0, 0, 2.5),  Vec3(10, 0, 2.4), Vec3(10, 8, 2.6), Vec3(0, 8, 2.5),
                                   Vec3(5, 0, 0.5),  Vec3(10, 4, 0.4), Vec3(5, 8, 0.6),  Vec3(0, 4, 0.5)};
  return kAnchors[id];
}

/// A chained group a->b (each row's reference is the previous row's anchor b),
/// as the office sim's TDMA rounds make them, exact at p_w_tag plus `errors`.
std::vector<EkfTdoaRow> chainAt(const Vec3& p_w_tag, const std::vector<std::uint32_t>& ids,
                                const std::vector<double>& errors, double sigma_m) {
  std::vector<EkfTdoaRow> rows;
  for (std::size_t k = 0; k + 1 < ids.size(); ++k) {
    EkfTdoaRow r;
    r.anchor_a = ids[k];
    r.anchor_b = ids[k + 1];
    r.p_w_anchor_a = anchor(r.anchor_a);
    r.p_w_anchor_b = anchor(r.anchor_b);
    r.diff_m = (p_w_tag - r.p_w_anchor_b).norm() - (p_w_tag - r.p_w_anchor_a).norm() + errors.at(k);
    r.sigma_m = sigma_m;
    rows.push_back(r);
  }
  return rows;
}

TEST(EkfTdoaGroup, CovarianceCorrelatesRowsThroughSharedAnchors) {
  // Rows: (0->1), (1->2) chain, (0->2) closes the triangle, (0->1) again, (3->4) disjoint.
  std::vector<EkfTdoaRow> rows(5);
  const std::uint32_t ab[5][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 1}, {3, 4}};
  const double sigma[5] = {0.2, 0.3, 0.4, 0.5, 0.6};
  for (int i = 0; i < 5; ++i) {
    rows[static_cast<std::size_t>(i)].anchor_a = ab[i][0];
    rows[static_cast<std::size_t>(i)].anchor_b = ab[i][1];
    rows[static_cast<std::size_t>(i)].sigma_m = sigma[i];
  }
  const double share = 0.8;
  const EkfGroupMat R = tdoaGroupCovariance(rows.data(), 5, share);
  ASSERT_EQ(R.rows(), 5);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(R(i, i), sigma[i] * sigma[i], 1e-15);
  EXPECT_NEAR((R - R.transpose()).cwiseAbs().maxCoeff(), 0.0, 0.0);
  // Chain: anchor 1 is b of row 0 and a of row 1: -share/2.
  EXPECT_NEAR(R(0, 1), -0.5 * share * 0.2 * 0.3, 1e-15);
  // Common reference 0: +share/2; common b (2): +share/2.
  EXPECT_NEAR(R(0, 2), 0.5 * share * 0.2 * 0.4, 1e-15);
  EXPECT_NEAR(R(1, 2), 0.5 * share * 0.3 * 0.4, 1e-15);
  // The same pair twice: both paths shared, fully correlated path part.
  EXPECT_NEAR(R(0, 3), share * 0.2 * 0.5, 1e-15);
  // Disjoint pair: independent.
  for (int i = 0; i < 4; ++i) EXPECT_EQ(R(i, 4), 0.0);
  // The triangle (0->1) + (1->2) = (0->2) is singular in the paths alone; the
  // row-specific part keeps R positive definite.
  EXPECT_EQ(Eigen::LLT<EkfGroupMat>(R).info(), Eigen::Success);
  const EkfGroupMat R0 = tdoaGroupCovariance(rows.data(), 5, 0.0);
  EXPECT_NEAR((R0 - EkfGroupMat(R0.diagonal().asDiagonal())).cwiseAbs().maxCoeff(), 0.0, 0.0);
  expectThrowsNaming([&] { tdoaGroupCovariance(rows.data(), kEkfMaxGroupRows + 1, share); }, "n must be");
}

TEST(EkfTdoaGroup, ChiSquareQuantiles) {
  EXPECT_NEAR(chiSquare999(1), 10.828, 1e-3);
  EXPECT_NEAR(chiSquare999(2), 13.816, 1e-3);
  EXPECT_NEAR(chiSquare999(4), 18.467, 1e-3);
  EXPECT_NEAR(chiSquare999(16), 39.252, 1e-3);
  for (int k = 2; k <= kEkfMaxGroupRows; ++k) EXPECT_GT(chiSquare999(k), chiSquare999(k - 1));
  expectThrowsNaming([] { chiSquare999(0); }, "dof");
  expectThrowsNaming([] { chiSquare999(kEkfMaxGroupRows + 1); }, "dof");
}

// One iteration, no loss, no gate in the way: the joint update is the
// textbook one with the full (correlated) R, Joseph form, then the reset.
TEST(EkfTdoaGroup, OneIterationIsTheTextbookJointUpdateWithCorrelatedR) {
  std::mt19937 rng(71);
  for (int c = 0; c < 10; ++c) {
    EkfState x;
    x.R_w_b = randomRotation(rng);
    x.p_w_b = Vec3(5, 4, 1.2) + randomVec(rng, 1.0);
    x.v_w = randomVec(rng, 1.0);
    const Mat15 P = randomCovariance(rng);
    EkfParams params;
    params.group_iterations = 1;
    params.gate_group_scale = std::numeric_limits<double>::infinity();
    ErrorStateEkf ekf(params);
    ekf.initialize(0, x, P);
    const Vec3 lever(0.06, 0.0, 0.1);
    const Vec3 p_w_tag = x.R_w_b * lever + x.p_w_b;
    const std::vector<EkfTdoaRow> rows = chainAt(p_w_tag, {2, 4, 6, 0, 5}, {0.1, -0.2, 0.05, 0.15}, 0.3);
    const int n = static_cast<int>(rows.size());
    const EkfGroupResult res = ekf.updateTdoaGroup(rows.data(), n, lever);
    ASSERT_EQ(res.accepted, n);
    EXPECT_EQ(res.iterations, 1);

    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, 15);
    Eigen::VectorXd y(n);
    for (int i = 0; i < n; ++i) {
      const EkfPrediction<1> p = predictTdoa(x, rows[static_cast<std::size_t>(i)].p_w_anchor_a,
                                             rows[static_cast<std::size_t>(i)].p_w_anchor_b, lever);
      H.block(i, 0, 1, 6) = p.H;
      y(i) = rows[static_cast<std::size_t>(i)].diff_m - p.h(0);
      EXPECT_NEAR(res.innovation[i], y(i), 1e-12);
    }
    const Eigen::MatrixXd R = tdoaGroupCovariance(rows.data(), n, params.tdoa_path_share);
    const Eigen::MatrixXd S = H * P * H.transpose() + R;
    EXPECT_NEAR(res.mahalanobis_sq, y.dot(S.llt().solve(y)), 1e-9);
    const Eigen::MatrixXd K = P * H.transpose() * S.inverse();
    const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(15, 15) - K * H;
    Mat15 P_ref = IKH * P * IKH.transpose() + K * R * K.transpose();
    const Vec15 dx = K * y;
    Mat15 G = Mat15::Identity();
    G.topLeftCorner<3, 3>() = so3::rightJacobian(dx.head<3>());
    P_ref = G * P_ref * G.transpose();
    EXPECT_LE(x.retract(dx).local(ekf.state()).norm(), 1e-10) << "case " << c;
    EXPECT_LE((ekf.covariance() - P_ref).cwiseAbs().maxCoeff(), 1e-10 * std::max(1.0, P.norm())) << "case " << c;
  }
}

// Iterated: the result is the Gauss-Newton fixed point of prior + likelihood,
// P^-1 d = H(x+)^T R^-1 (z - h(x+)) (lever arm 0: the position chart is
// additive and H has no rotation columns, so the condition is exact).
TEST(EkfTdoaGroup, IterationsReachTheMapOfPriorAndLikelihood) {
  std::mt19937 rng(5);
  for (int c = 0; c < 5; ++c) {
    EkfState x;
    x.p_w_b = Vec3(5, 4, 1.2) + randomVec(rng, 0.5);
    const Mat15 P = diagonalCovariance(0.05, 1.0, 0.3, 0.05, 0.005);
    EkfParams params;
    params.group_iterations = 30;
    params.gate_group_scale = std::numeric_limits<double>::infinity();
    ErrorStateEkf ekf(params);
    ekf.initialize(0, x, P);
    // The truth 1 m away: a linearization a single update gets visibly wrong.
    const Vec3 p_true = x.p_w_b + Vec3(0.8, -0.5, 0.2);
    const std::vector<EkfTdoaRow> rows = chainAt(p_true, {0, 1, 2, 3, 4, 5}, {0, 0, 0, 0, 0}, 0.1);
    const int n = static_cast<int>(rows.size());
    const EkfGroupResult res = ekf.updateTdoaGroup(rows.data(), n, Vec3::Zero());
    ASSERT_EQ(res.accepted, n);
    EXPECT_LT(res.iterations, 30);  // converged before the limit
    const EkfState& xp = ekf.state();
    const Vec15 d = x.local(xp);
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, 15);
    Eigen::VectorXd r(n);
    for (int i = 0; i < n; ++i) {
      const EkfPrediction<1> p = predictTdoa(xp, rows[static_cast<std::size_t>(i)].p_w_anchor_a,
                                             rows[static_cast<std::size_t>(i)].p_w_anchor_b, Vec3::Zero());
      H.block(i, 0, 1, 6) = p.H;
      r(i) = rows[static_cast<std::size_t>(i)].diff_m - p.h(0);
    }
    const Eigen::MatrixXd R = tdoaGroupCovariance(rows.data(), n, params.tdoa_path_share);
    const Vec15 gradient = P.inverse() * d - H.transpose() * R.llt().solve(r);
    EXPECT_LE(gradient.norm(), 1e-6 * (P.inverse() * d).norm()) << "case " << c;
    // And it is closer to the truth than the one-step update.
    EkfParams one = params;
    one.group_iterations = 1;
    ErrorStateEkf ekf1(one);
    ekf1.initialize(0, x, P);
    ekf1.updateTdoaGroup(rows.data(), n, Vec3::Zero());
    EXPECT_LT((xp.p_w_b - p_true).norm(), (ekf1.state().p_w_b - p_true).norm()) << "case " << c;
  }
}

TEST(EkfTdoaGroup, GateDropsTheOutlierRowAndKeepsTheRest) {
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(5, 4, 1.2)), Vec3::Zero(), ImuBias());
  ErrorStateEkf ekf;
  ekf.initialize(0, x0, diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001));
  // Row 2 (anchors 6 -> 0) measured 4 m long: NLOS far beyond its 0.15 m sigma.
  const std::vector<EkfTdoaRow> rows = chainAt(x0.p_w_b, {2, 4, 6, 0, 5}, {0.05, -0.03, 4.0, 0.02}, 0.15);
  const EkfGroupResult res = ekf.updateTdoaGroup(rows.data(), 4, Vec3::Zero());
  EXPECT_EQ(res.gated, 1);
  EXPECT_EQ(res.accepted, 3);
  EXPECT_EQ(res.status[2], UpdateStatus::kGated);
  for (int i : {0, 1, 3}) EXPECT_EQ(res.status[i], UpdateStatus::kAccepted);
  EXPECT_NEAR(res.innovation[2], 4.0, 1e-9);
  EXPECT_LE(res.mahalanobis_sq, chiSquare999(3));
  // The outlier did not pull the state: it stays near the truth.
  EXPECT_LT((ekf.state().p_w_b - x0.p_w_b).norm(), 0.1);
  EXPECT_EQ(ekf.counters().tdoa.gated, 1u);
  EXPECT_EQ(ekf.counters().tdoa.accepted, 3u);
}

TEST(EkfTdoaGroup, GateRejectsAWhollyInconsistentGroupAndLeavesTheState) {
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(5, 4, 1.2)), Vec3::Zero(), ImuBias());
  ErrorStateEkf ekf;
  const Mat15 P0 = diagonalCovariance(0.01, 0.05, 0.1, 0.01, 0.001);
  ekf.initialize(0, x0, P0);
  // Every row 3 m off: no subset is consistent with the prior.
  const std::vector<EkfTdoaRow> rows = chainAt(x0.p_w_b, {2, 4, 6, 0, 5}, {3.0, -3.0, 3.0, -3.0}, 0.15);
  const EkfGroupResult res = ekf.updateTdoaGroup(rows.data(), 4, Vec3::Zero());
  EXPECT_EQ(res.gated, 4);
  EXPECT_EQ(res.accepted, 0);
  EXPECT_EQ(ekf.state().local(x0).norm(), 0.0);
  EXPECT_EQ((ekf.covariance() - P0).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(ekf.counters().tdoa.gated, 4u);

  // Gate off: the same group is taken.
  EkfParams open;
  open.gate_group_scale = std::numeric_limits<double>::infinity();
  ErrorStateEkf ekf_open(open);
  ekf_open.initialize(0, x0, P0);
  EXPECT_EQ(ekf_open.updateTdoaGroup(rows.data(), 4, Vec3::Zero()).accepted, 4);
}

TEST(EkfTdoaGroup, HuberDownWeightsTheLargeResidualRow) {
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(5, 4, 1.2)), Vec3::Zero(), ImuBias());
  EkfParams params;
  params.gate_group_scale = std::numeric_limits<double>::infinity();
  HuberLoss huber(1.345);
  const std::vector<EkfTdoaRow> rows = chainAt(x0.p_w_b, {2, 4, 6, 0, 5}, {0.0, 0.0, 1.0, 0.0}, 0.15);
  ErrorStateEkf robust(params), plain(params);
  robust.initialize(0, x0, diagonalCovariance(0.01, 0.3, 0.1, 0.01, 0.001));
  plain.initialize(0, x0, diagonalCovariance(0.01, 0.3, 0.1, 0.01, 0.001));
  const EkfGroupResult r = robust.updateTdoaGroup(rows.data(), 4, Vec3::Zero(), &huber);
  plain.updateTdoaGroup(rows.data(), 4, Vec3::Zero());
  EXPECT_LT(r.weight[2], 0.5);
  for (int i : {0, 1, 3}) EXPECT_GT(r.weight[i], 0.5);
  // The robust update stays closer to the truth than the Gaussian one.
  EXPECT_LT((robust.state().p_w_b - x0.p_w_b).norm(), 0.7 * (plain.state().p_w_b - x0.p_w_b).norm());
}

TEST(EkfTdoaGroup, InvalidArgumentsNameTheParameter) {
  ErrorStateEkf ekf;
  std::vector<EkfTdoaRow> rows = chainAt(Vec3(5, 4, 1.2), {2, 4, 6}, {0, 0}, 0.15);
  EXPECT_THROW(ekf.updateTdoaGroup(rows.data(), 2, Vec3::Zero()), std::logic_error);  // not initialized
  ekf.initialize(0, EkfState(Pose3(Mat3::Identity(), Vec3(5, 4, 1.2)), Vec3::Zero(), ImuBias()),
                 diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001));
  expectThrowsNaming([&] { ekf.updateTdoaGroup(rows.data(), kEkfMaxGroupRows + 1, Vec3::Zero()); }, "n must be");
  expectThrowsNaming([&] { ekf.updateTdoaGroup(nullptr, 2, Vec3::Zero()); }, "n must be");
  rows[1].sigma_m = 0.0;
  expectThrowsNaming([&] { ekf.updateTdoaGroup(rows.data(), 2, Vec3::Zero()); }, "sigma_m");
  rows[1].sigma_m = 0.15;
  rows[1].anchor_b = rows[1].anchor_a;
  expectThrowsNaming([&] { ekf.updateTdoaGroup(rows.data(), 2, Vec3::Zero()); }, "anchors a and b");
  rows[1].anchor_b = 6;
  rows[0].diff_m = std::numeric_limits<double>::quiet_NaN();
  expectThrowsNaming([&] { ekf.updateTdoaGroup(rows.data(), 2, Vec3::Zero()); }, "diff_m");
  EXPECT_EQ(ekf.updateTdoaGroup(rows.data(), 0, Vec3::Zero()).rows, 0);  // empty group: nothing
  EkfParams bad;
  bad.tdoa_path_share = 1.0;
  expectThrowsNaming([&] { ErrorStateEkf e(bad); }, "tdoa_path_share");
  bad = EkfParams();
  bad.gate_group_scale = 0.0;
  expectThrowsNaming([&] { ErrorStateEkf e(bad); }, "gate_group_scale");
  bad = EkfParams();
  bad.group_iterations = 0;
  expectThrowsNaming([&] { ErrorStateEkf e(bad); }, "group_iterations");
}

TEST(EkfTdoaGroup, GroupUpdateDoesNotAllocate) {
  ErrorStateEkf ekf;
  ekf.initialize(0, EkfState(Pose3(Mat3::Identity(), Vec3(5, 4, 1.2)), Vec3::Zero(), ImuBias()),
                 diagonalCovariance(0.01, 0.3, 0.1, 0.01, 0.001));
  const std::vector<EkfTdoaRow> rows = chainAt(Vec3(5.2, 4.1, 1.2), {0, 1, 2, 3, 4, 5, 6, 7}, std::vector<double>(7, 0.1), 0.15);
  HuberLoss huber(1.345);
  testing::NewCounter counter;
  for (int k = 0; k < 10; ++k) ekf.updateTdoaGroup(rows.data(), 7, Vec3(0.06, 0, 0.1), &huber);
  EXPECT_EQ(counter.count(), 0u);
}

ImuSample sampleAt(std::int64_t t_ns, const Vec3& gyro, const Vec3& accel) {
  ImuSample s;
  s.t_ns = t_ns;
  s.gyro_rad_s = gyro;
  s.accel_m_s2 = accel;
  return s;
}

// An interval above gap_threshold_s adds exactly the gap's input variance on
// top of the white noise (the rest of the step is identical).
TEST(EkfImuGap, GapIntervalAddsTheUnmeasuredMotionVariance) {
  EkfParams with_gap;
  EkfParams no_gap;
  no_gap.imu.gap_accel_sigma_m_s2 = 0.0;
  no_gap.imu.gap_gyro_sigma_rad_s = 0.0;
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(1, 2, 1)), Vec3(0.5, 0, 0), ImuBias());
  const Mat15 P0 = diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001);
  const Vec3 f(0.1, 0.0, 9.81), w(0.0, 0.0, 0.2);
  for (const double dt : {0.01, 0.3}) {
    ErrorStateEkf a(with_gap), b(no_gap);
    a.initialize(0, x0, P0);
    b.initialize(0, x0, P0);
    a.propagate(sampleAt(0, w, f));
    b.propagate(sampleAt(0, w, f));
    const std::int64_t t1 = static_cast<std::int64_t>(std::llround(dt * 1e9));
    ASSERT_EQ(a.propagate(sampleAt(t1, w, f)), PropagateStatus::kPropagated) << dt;
    ASSERT_EQ(b.propagate(sampleAt(t1, w, f)), PropagateStatus::kPropagated) << dt;
    EXPECT_LE(a.state().local(b.state()).norm(), 0.0);
    Mat15 Q = Mat15::Zero();
    if (dt > with_gap.imu.gap_threshold_s) {
      const double ga2 = std::pow(with_gap.imu.gap_accel_sigma_m_s2, 2), gg2 = std::pow(with_gap.imu.gap_gyro_sigma_rad_s, 2);
      for (int i = 0; i < 3; ++i) {
        Q(i, i) = gg2 * dt * dt;
        Q(3 + i, 3 + i) = ga2 * std::pow(dt, 4) / 4.0;
        Q(6 + i, 6 + i) = ga2 * dt * dt;
        Q(3 + i, 6 + i) = Q(6 + i, 3 + i) = ga2 * std::pow(dt, 3) / 2.0;
      }
    }
    EXPECT_LE((a.covariance() - b.covariance() - Q).cwiseAbs().maxCoeff(), 1e-12) << dt;
  }
}

// A 0.3 s gap (below the default max_imu_dt_s) is bridged, and the samples
// after it propagate as before: the filter's time is not stuck before the gap.
TEST(EkfImuGap, ShortGapIsBridgedAndLaterSamplesPropagate) {
  ErrorStateEkf ekf;
  ekf.initialize(0, EkfState(Pose3(Mat3::Identity(), Vec3(1, 2, 1)), Vec3::Zero(), ImuBias()),
                 diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001));
  const Vec3 f(0.0, 0.0, 9.81);
  std::int64_t t = 0;
  ekf.propagate(sampleAt(t, Vec3::Zero(), f));
  for (int k = 0; k < 10; ++k) ASSERT_EQ(ekf.propagate(sampleAt(t += 5'000'000, Vec3::Zero(), f)), PropagateStatus::kPropagated);
  const double sigma_v_before = std::sqrt(ekf.covariance()(6, 6));
  EXPECT_EQ(ekf.propagate(sampleAt(t += 300'000'000, Vec3::Zero(), f)), PropagateStatus::kPropagated);
  EXPECT_GT(std::sqrt(ekf.covariance()(6, 6)), sigma_v_before + 0.4);  // 2 m/s^2 x 0.3 s of unknown motion
  EXPECT_EQ(ekf.propagate(sampleAt(t += 5'000'000, Vec3::Zero(), f)), PropagateStatus::kPropagated);
  EXPECT_EQ(ekf.t_ns(), t);
  EXPECT_EQ(ekf.counters().imu_gaps, 0u);
}

}  // namespace
}  // namespace rilo
