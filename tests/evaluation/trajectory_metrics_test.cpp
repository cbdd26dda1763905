// Association, APE and RPE against hand-computed values.
#include "evaluation/trajectory_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "math/so3.h"

namespace rilo {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

Mat3 yaw(double rad) { return so3::exp(Vec3(0.0, 0.0, rad)); }

GroundTruthPose truthPose(std::int64_t t_ns, const Mat3& R, const Vec3& p) {
  GroundTruthPose g;
  g.t_ns = t_ns;
  g.p_w_b = p;
  g.q_w_b = Quat(R);
  return g;
}

/// Ground truth at `hz` over [0, duration_s], pose given as a function of t (s).
std::vector<GroundTruthPose> truthAlong(double duration_s, double hz,
                                        const std::function<Pose3(double)>& pose_at) {
  std::vector<GroundTruthPose> truth;
  const auto n = static_cast<std::int64_t>(std::llround(duration_s * hz));
  const auto dt_ns = static_cast<std::int64_t>(std::llround(1e9 / hz));
  for (std::int64_t k = 0; k <= n; ++k) {
    const Pose3 T = pose_at(static_cast<double>(k * dt_ns) * 1e-9);
    truth.push_back(truthPose(k * dt_ns, T.R, T.p));
  }
  return truth;
}

/// Walk along x at 1 m/s facing +x, z = 1.2 m.
Pose3 straightWalk(double t) { return Pose3(Mat3::Identity(), Vec3(t, 0.0, 1.2)); }

/// The estimate: the ground truth's times and poses, modified by `f`.
TumTrajectory estimateFrom(const std::vector<GroundTruthPose>& truth,
                           const std::function<Pose3(double, const Pose3&)>& f) {
  TumTrajectory est;
  for (const auto& g : truth) est.push_back({g.t_ns, f(static_cast<double>(g.t_ns) * 1e-9, g.pose())});
  return est;
}

void expectAllStats(const ErrorStats& s, double value, double tol) {
  EXPECT_NEAR(s.mean, value, tol);
  EXPECT_NEAR(s.median, value, tol);
  EXPECT_NEAR(s.rmse, value, tol);
  EXPECT_NEAR(s.max, value, tol);
}

TEST(Association, NearestInTimeWithinToleranceAndCountsTheRest) {
  std::vector<GroundTruthPose> truth;
  for (std::int64_t k = 0; k < 5; ++k) truth.push_back(truthPose(1'000'000'000 + k * 100'000'000, Mat3::Identity(), Vec3::Zero()));
  // truth at 1.0, 1.1, 1.2, 1.3, 1.4 s
  const TumTrajectory est = {
      {940'000'000, Pose3()},    // 60 ms before the first: unmatched
      {960'000'000, Pose3()},    // 40 ms before the first -> 0
      {1'130'000'000, Pose3()},  // nearer 1.1 -> 1
      {1'150'000'000, Pose3()},  // tie between 1.1 and 1.2 -> the later, 2
      {1'349'000'000, Pose3()},  // 49 ms after 1.3 vs 51 ms before 1.4 -> 3
      {1'450'000'000, Pose3()},  // exactly the tolerance after the last -> 4
      {1'450'000'001, Pose3()},  // 1 ns beyond: unmatched
  };
  const PoseAssociation a = associateByTime(est, truth, 50'000'000);
  ASSERT_EQ(a.pairs.size(), 5u);
  const std::vector<std::pair<std::size_t, std::size_t>> expected = {{1, 0}, {2, 1}, {3, 2}, {4, 3}, {5, 4}};
  EXPECT_EQ(a.pairs, expected);
  EXPECT_EQ(a.unmatched, (std::vector<std::size_t>{0, 6}));
  EXPECT_EQ(a.max_abs_dt_ns, 50'000'000);
  EXPECT_EQ(associateByTime(est, truth, 0).pairs.size(), 0u);
  EXPECT_EQ(associateByTime(est, {}, 50'000'000).unmatched.size(), est.size());
  EXPECT_THROW(associateByTime(est, truth, -1), std::invalid_argument);
}

TEST(Ape, ConstantOffsetGivesTheOffsetAndNoRelativeError) {
  const auto truth = truthAlong(30.0, 100.0, straightWalk);
  const Vec3 offset(0.3, -0.4, 1.2);  // horizontal 0.5, vertical 1.2, 3D 1.3
  const auto est = estimateFrom(truth, [&](double, const Pose3& T) { return Pose3(T.R, T.p + offset); });
  // Tolerances below the sample spacing: only pairs exactly 1 s / 10 m apart.
  EvaluationParams params;
  params.rpe_time.rel_tol = 0.0049;
  params.rpe_distance.rel_tol = 0.00049;
  const TrajectoryEvaluation ev = evaluateTrajectory(est, truth, params);
  EXPECT_EQ(ev.association.pairs.size(), truth.size());
  EXPECT_TRUE(ev.association.unmatched.empty());
  expectAllStats(ev.ape.ape_3d, 1.3, 1e-12);
  expectAllStats(ev.ape.ape_horizontal, 0.5, 1e-12);
  expectAllStats(ev.ape.ape_vertical, 1.2, 1e-12);
  EXPECT_NEAR(ev.ape.vertical_bias_m, 1.2, 1e-12);
  EXPECT_EQ(ev.ape.ape_3d.count, truth.size());
  // 1 s at 100 Hz: every pose up to 29 s starts a pair 100 samples on.
  EXPECT_EQ(ev.rpe_time.translation_m.count, truth.size() - 100);
  expectAllStats(ev.rpe_time.translation_m, 0.0, 1e-9);
  expectAllStats(ev.rpe_time.rotation_deg, 0.0, 1e-9);
  // 10 m at 1 m/s: 10 s apart.
  EXPECT_EQ(ev.rpe_distance.translation_m.count, truth.size() - 1000);
  expectAllStats(ev.rpe_distance.translation_m, 0.0, 1e-9);
  // positionErrorAgainst (used by `rilo replay`) measures the same.
  const PositionErrorStats same = positionErrorAgainst(est, truth);
  EXPECT_DOUBLE_EQ(same.ape_3d.mean, ev.ape.ape_3d.mean);
  EXPECT_EQ(same.ape_3d.count, ev.ape.ape_3d.count);
}

TEST(Ape, UnmatchedPosesAreNotInTheStatistics) {
  const auto truth = truthAlong(10.0, 50.0, straightWalk);
  auto est = estimateFrom(truth, [](double, const Pose3& T) { return Pose3(T.R, T.p + Vec3(0.0, 0.0, 0.1)); });
  est.push_back({truth.back().t_ns + 60'000'000, Pose3(Mat3::Identity(), Vec3(100.0, 0.0, 0.0))});
  const TrajectoryEvaluation ev = evaluateTrajectory(est, truth);
  EXPECT_EQ(ev.association.unmatched, (std::vector<std::size_t>{est.size() - 1}));
  expectAllStats(ev.ape.ape_3d, 0.1, 1e-12);
  EXPECT_EQ(ev.ape.ape_3d.count, truth.size());
}

TEST(TrackedShare, CountsTheTimeAPoseIsAtMostMaxAgeOld) {
  constexpr std::int64_t kS = 1'000'000'000;
  // Poses at 10 Hz over 2-5 s and 8-9 s of a 0-10 s recording, then one at 9.5 s.
  TumTrajectory poses;
  for (std::int64_t t = 2 * kS; t <= 5 * kS; t += kS / 10) poses.push_back({t, Pose3()});
  for (std::int64_t t = 8 * kS; t <= 9 * kS; t += kS / 10) poses.push_back({t, Pose3()});
  poses.push_back({9 * kS + kS / 2, Pose3()});
  // Covered: [2, 6) (the last pose at 5 s stays fresh 1 s) and [8, 10): 6 s of 10.
  EXPECT_NEAR(trackedShare(poses, 0, 10 * kS), 0.6, 1e-12);
  // With a 0.2 s limit: [2, 5.2), [8, 9.2) and [9.5, 9.7): 3.2 + 1.2 + 0.2 = 4.6 s.
  EXPECT_NEAR(trackedShare(poses, 0, 10 * kS, kS / 5), 0.46, 1e-12);
  // Only the interval counts: [3, 4] is all covered, [6, 7] none.
  EXPECT_NEAR(trackedShare(poses, 3 * kS, 4 * kS), 1.0, 1e-12);
  EXPECT_EQ(trackedShare(poses, 6 * kS, 7 * kS), 0.0);
  EXPECT_EQ(trackedShare({}, 0, 10 * kS), 0.0);
  EXPECT_EQ(trackedShare(poses, 5 * kS, 5 * kS), 0.0);
}

TEST(TrackedShare, BadInputIsRejected) {
  TumTrajectory poses{{2, Pose3()}, {1, Pose3()}};
  EXPECT_THROW(trackedShare(poses, 0, 10), std::invalid_argument);
  EXPECT_THROW(trackedShare({}, 0, 10, -1), std::invalid_argument);
}

TEST(Rpe, ConstantRotationDriftGivesTheDriftPerSecond) {
  // Standing still, the estimate's yaw drifts at 3 deg/s: each 1 s pair has
  // a relative rotation error of exactly 3 deg and no translation error.
  const auto truth = truthAlong(20.0, 50.0, [](double) { return Pose3(Mat3::Identity(), Vec3(2.0, 3.0, 1.0)); });
  const double rate = 3.0 * kDeg;
  const auto est = estimateFrom(truth, [&](double t, const Pose3& T) { return Pose3(yaw(rate * t), T.p); });
  const RelativePoseErrorStats rpe =
      relativePoseError(est, truth, associateByTime(est, truth), RpeParams{1.0, RpeDelta::kSeconds, 0.01});
  EXPECT_EQ(rpe.translation_m.count, truth.size() - 50);
  expectAllStats(rpe.rotation_deg, 3.0, 1e-9);
  expectAllStats(rpe.translation_m, 0.0, 1e-12);
  // Over 2 s: 6 deg.
  const RelativePoseErrorStats rpe2 =
      relativePoseError(est, truth, associateByTime(est, truth), RpeParams{2.0, RpeDelta::kSeconds, 0.005});
  expectAllStats(rpe2.rotation_deg, 6.0, 1e-9);
}

TEST(Rpe, RelativeMotionIsExpressedInTheBodyFrameAtTheStart) {
  // Walking along x at 1 m/s; the estimate has the right positions but a
  // heading off by a constant 90 deg. The relative rotation is right (0 deg);
  // the relative translation, in the body frame at i, is (1, 0, 0) for the
  // truth and (0, -1, 0) for the estimate: error sqrt(2) for every 1 s pair.
  const auto truth = truthAlong(10.0, 100.0, straightWalk);
  const auto est = estimateFrom(truth, [](double, const Pose3& T) { return Pose3(yaw(90.0 * kDeg) * T.R, T.p); });
  const RelativePoseErrorStats rpe =
      relativePoseError(est, truth, associateByTime(est, truth), RpeParams{1.0, RpeDelta::kSeconds, 0.005});
  expectAllStats(rpe.translation_m, std::sqrt(2.0), 1e-9);
  expectAllStats(rpe.rotation_deg, 0.0, 1e-9);
  // APE sees no error at all: positions only.
  expectAllStats(absolutePositionError(est, truth, associateByTime(est, truth)).ape_3d, 0.0, 0.0);
}

TEST(Rpe, DriftingHeadingWhileWalking) {
  // Yaw drift of 2 deg/s while walking at 1 m/s along x: the 1 s pair
  // starting at t_i has rotation error 2 deg and translation error
  // |(1,0,0) - R_z(-2 deg/s t_i)(1,0,0)| = 2 sin(t_i deg).
  const auto truth = truthAlong(30.0, 10.0, straightWalk);
  const auto est = estimateFrom(truth, [](double t, const Pose3& T) { return Pose3(yaw(2.0 * kDeg * t), T.p); });
  const PoseAssociation a = associateByTime(est, truth);
  const RpeParams params{1.0, RpeDelta::kSeconds, 0.05};  // below the 0.1 s spacing: exact pairs only
  const auto pairs = rpePairs(est, truth, a, params);
  ASSERT_EQ(pairs.size(), truth.size() - 10);
  const RelativePoseErrorStats rpe = relativePoseError(est, truth, a, params);
  expectAllStats(rpe.rotation_deg, 2.0, 1e-9);
  const double last_start_s = 29.0;
  EXPECT_NEAR(rpe.translation_m.max, 2.0 * std::sin(last_start_s * kDeg), 1e-9);
  double sum = 0.0;
  for (std::size_t k = 0; k < pairs.size(); ++k) sum += 2.0 * std::sin(0.1 * static_cast<double>(k) * kDeg);
  EXPECT_NEAR(rpe.translation_m.mean, sum / static_cast<double>(pairs.size()), 1e-9);
}

TEST(Rpe, TimePairsSkipGapsInTheEstimate) {
  const auto truth = truthAlong(10.0, 10.0, straightWalk);
  TumTrajectory est;
  for (const auto& g : truth) {
    const double t = static_cast<double>(g.t_ns) * 1e-9;
    if (t > 3.05 && t < 6.95) continue;  // a 4 s hole: no pair may span it
    est.push_back({g.t_ns, g.pose()});
  }
  const PoseAssociation a = associateByTime(est, truth);
  const auto pairs = rpePairs(est, truth, a, RpeParams{1.0, RpeDelta::kSeconds, 0.05});
  for (const auto& [i, j] : pairs) {
    const double dt = static_cast<double>(est[a.pairs[j].first].t_ns - est[a.pairs[i].first].t_ns) * 1e-9;
    EXPECT_NEAR(dt, 1.0, 1e-9);
  }
  // Starts at 0.0..2.0 s and 7.0..9.0 s: 21 + 21.
  EXPECT_EQ(pairs.size(), 42u);
}

TEST(Rpe, TenMetrePairsFollowTheGroundTruthPath) {
  // 100 Hz ground truth: 20 m along x (20 s), 5 s standing, 20 m along y
  // (20 s). Path length s(t) = min(t, 20) + max(0, t - 25). The estimate is
  // at 10 Hz, on the ground truth.
  const auto path = [](double t) {
    if (t <= 20.0) return Pose3(Mat3::Identity(), Vec3(t, 0.0, 1.0));
    if (t <= 25.0) return Pose3(yaw(90.0 * kDeg), Vec3(20.0, 0.0, 1.0));
    return Pose3(yaw(90.0 * kDeg), Vec3(20.0, t - 25.0, 1.0));
  };
  const auto truth = truthAlong(45.0, 100.0, path);
  TumTrajectory est;
  for (std::size_t k = 0; k < truth.size(); k += 10) est.push_back({truth[k].t_ns, truth[k].pose()});
  ASSERT_EQ(est.size(), 451u);
  const PoseAssociation a = associateByTime(est, truth);
  ASSERT_EQ(a.pairs.size(), est.size());
  const RpeParams params{10.0, RpeDelta::kMeters, 0.075};
  const auto pairs = rpePairs(est, truth, a, params);
  const auto time_s = [&](std::size_t assoc) { return static_cast<double>(est[a.pairs[assoc].first].t_ns) * 1e-9; };
  const auto pairStartingAt = [&](double t) -> std::pair<double, double> {
    for (const auto& [i, j] : pairs) {
      if (std::abs(time_s(i) - t) < 1e-6) return {time_s(i), time_s(j)};
    }
    return {-1.0, -1.0};
  };
  EXPECT_NEAR(pairStartingAt(0.0).second, 10.0, 1e-9);   // s 0 -> 10
  EXPECT_NEAR(pairStartingAt(15.0).second, 30.0, 1e-9);  // s 15 -> 25: the 5 s stop does not count
  EXPECT_NEAR(pairStartingAt(22.0).second, 35.0, 1e-9);  // standing (s 20) -> 30
  EXPECT_NEAR(pairStartingAt(35.0).second, 45.0, 1e-9);  // s 30 -> 40, the end
  EXPECT_NEAR(pairStartingAt(35.7).second, 45.0, 1e-9);  // s 30.7 -> 40: 9.3 m, within 7.5 %
  EXPECT_LT(pairStartingAt(35.8).first, 0.0);            // 9.2 m: no pair
  // Every start up to 35.7 s has its pair: 358.
  EXPECT_EQ(pairs.size(), 358u);
  const std::vector<double> s = groundTruthPathLength(truth);
  EXPECT_NEAR(s.back(), 40.0, 1e-9);
  for (const auto& [i, j] : pairs) {
    EXPECT_LT(i, j);
    EXPECT_LE(std::abs(s[a.pairs[j].second] - s[a.pairs[i].second] - 10.0), 0.75 + 1e-9);
  }
  // The estimate is the truth: no error.
  const RelativePoseErrorStats rpe = relativePoseError(est, truth, a, params);
  EXPECT_EQ(rpe.translation_m.count, 358u);
  expectAllStats(rpe.translation_m, 0.0, 1e-9);
  expectAllStats(rpe.rotation_deg, 0.0, 1e-6);
}

TEST(Rpe, TooShortForTheDeltaGivesNoPairs) {
  const auto truth = truthAlong(5.0, 50.0, straightWalk);  // 5 m
  const auto est = estimateFrom(truth, [](double, const Pose3& T) { return T; });
  const TrajectoryEvaluation ev = evaluateTrajectory(est, truth);
  EXPECT_EQ(ev.rpe_distance.translation_m.count, 0u);
  EXPECT_GT(ev.rpe_time.translation_m.count, 0u);
}

TEST(Rpe, BadInputIsRejected) {
  const auto truth = truthAlong(5.0, 50.0, straightWalk);
  auto est = estimateFrom(truth, [](double, const Pose3& T) { return T; });
  const PoseAssociation a = associateByTime(est, truth);
  EXPECT_THROW(rpePairs(est, truth, a, RpeParams{0.0, RpeDelta::kSeconds, 0.1}), std::invalid_argument);
  EXPECT_THROW(rpePairs(est, truth, a, RpeParams{-1.0, RpeDelta::kMeters, 0.1}), std::invalid_argument);
  EXPECT_THROW(rpePairs(est, truth, a, RpeParams{1.0, RpeDelta::kSeconds, 1.0}), std::invalid_argument);
  std::swap(est[3], est[4]);
  EXPECT_THROW(evaluateTrajectory(est, truth), std::invalid_argument);
}

TEST(Ape, HeightOffsetIsTheSignedMeanOfTheVerticalErrorWhileTheVerticalStatisticsAreMagnitudes) {
  const std::vector<Vec3> truth = {Vec3(0, 0, 1.25), Vec3(1, 0, 1.25), Vec3(2, 0, 1.25), Vec3(3, 0, 1.25)};
  // Noise around the truth: |dz| 0.2 everywhere, no offset.
  const std::vector<Vec3> noisy = {Vec3(0, 0, 1.45), Vec3(1, 0, 1.05), Vec3(2, 0, 1.45), Vec3(3, 0, 1.05)};
  const PositionErrorStats n = positionErrorStats(noisy, truth);
  EXPECT_NEAR(n.ape_vertical.mean, 0.2, 1e-12);
  EXPECT_NEAR(n.vertical_bias_m, 0.0, 1e-12);
  // A sunk tag: the same magnitudes, all below, so the offset is -0.2 ... -0.4.
  const std::vector<Vec3> sunk = {Vec3(0, 0, 1.05), Vec3(1, 0, 0.85), Vec3(2, 0, 1.05), Vec3(3, 0, 0.85)};
  const PositionErrorStats s = positionErrorStats(sunk, truth);
  EXPECT_NEAR(s.ape_vertical.mean, 0.3, 1e-12);
  EXPECT_NEAR(s.vertical_bias_m, -0.3, 1e-12);
  EXPECT_DOUBLE_EQ(positionErrorStats({}, {}).vertical_bias_m, 0.0);
}

}  // namespace
}  // namespace rilo
