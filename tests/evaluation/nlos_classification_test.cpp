#include "evaluation/nlos_classification.h"

#include <gtest/gtest.h>

#include <limits>

#include "estimation/noise/noise_model_factory.h"

namespace rilo {
namespace {

TEST(NlosClassification, LongRangesAreDownWeightedAndScoredAgainstTheLabels) {
  const std::vector<Vec3> anchors = {Vec3(0, 0, 2), Vec3(10, 0, 2), Vec3(0, 10, 2)};
  const Vec3 p_b_tag(0.0, 0.0, 0.1);
  std::vector<RangeImuEstimator::TimedPose> trajectory;
  for (int k = 0; k <= 10; ++k) trajectory.push_back({k * 100'000'000LL, Pose3(Mat3::Identity(), Vec3(0.5 * k, 3, 1.2))});

  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  const RangeModel model("asymmetric", noise);
  std::vector<RangeSample> ranges;
  auto add = [&](std::int64_t t_ns, std::uint32_t id, double excess_m, int los) {
    const Pose3& T = trajectory[static_cast<std::size_t>((t_ns + 50'000'000) / 100'000'000)].T_w_b;
    RangeSample r;
    r.t_ns = t_ns;
    r.anchor_id = id;
    r.range_m = (T.R * p_b_tag + T.p - anchors[id]).norm() + excess_m;
    r.los = los;
    ranges.push_back(r);
  };
  add(100'000'000, 0, 0.02, 1);   // LOS, small noise: kept
  add(210'000'000, 1, 2.0, 0);    // NLOS, 2 m long: down-weighted (nearest pose 200 ms)
  add(290'000'000, 2, 0.05, 0);   // NLOS with a tiny excess: not caught
  add(400'000'000, 1, -0.03, -1); // unlabelled
  add(500'000'000, 0, 3.0, 1);    // labelled LOS but 3 m long (a wrong label or an outlier): lost
  RangeSample far = ranges.back();
  far.t_ns = 5'000'000'000;  // no pose within 50 ms: skipped
  ranges.push_back(far);
  RangeSample unknown = ranges.front();
  unknown.t_ns = 5'100'000'000;
  unknown.anchor_id = 7;     // not an anchor: skipped
  ranges.push_back(unknown);

  const NlosClassification c = classifyRanges(ranges, trajectory, anchors, p_b_tag, model, noise.sigma_m);
  EXPECT_EQ(c.ranges, 5u);
  EXPECT_EQ(c.downweighted, 2u);
  EXPECT_EQ(c.labelled_nlos, 2u);
  EXPECT_EQ(c.nlos_downweighted, 1u);
  EXPECT_EQ(c.labelled_los, 2u);
  EXPECT_EQ(c.los_downweighted, 1u);
  EXPECT_DOUBLE_EQ(c.nlosCaught(), 0.5);
  EXPECT_DOUBLE_EQ(c.losLost(), 0.5);
  EXPECT_DOUBLE_EQ(c.downweightedFraction(), 0.4);
}

// A state holds the ranges of its next 50 ms (config/rilod.yaml): a range
// between two poses is judged where the walk between them puts the tag.
TEST(NlosClassification, ARangeBetweenTwoPosesIsJudgedWhereTheWalkPutsTheTagAtItsTime) {
  const std::vector<Vec3> anchors = {Vec3(-10, 0, 1.2)};  // behind, along the walk
  const std::vector<RangeImuEstimator::TimedPose> trajectory = {
      {0, Pose3(Mat3::Identity(), Vec3(0.0, 0, 1.2))}, {100'000'000, Pose3(Mat3::Identity(), Vec3(0.2, 0, 1.2))}};
  RangeNoiseParams noise;
  noise.sigma_m = 0.03;  // the decision point at about 0.064 m
  const RangeModel model("asymmetric", noise);
  RangeSample r;
  r.anchor_id = 0;
  r.t_ns = 40'000'000;  // 2 m/s: the tag is 0.08 m on from the first pose, 0.12 m short of the second
  r.range_m = 10.0 + 0.08;
  r.los = 1;
  const NlosClassification c = classifyRanges({r}, trajectory, anchors, Vec3::Zero(), model, noise.sigma_m);
  EXPECT_EQ(c.ranges, 1u);
  EXPECT_EQ(c.downweighted, 0u) << "at the nearest pose it would be 0.08 m long: 2.7 sigma, NLOS";
  r.range_m += 0.3;  // a real excess still is one
  EXPECT_EQ(classifyRanges({r}, trajectory, anchors, Vec3::Zero(), model, noise.sigma_m).downweighted, 1u);
}

TEST(NlosClassification, ShortRangesStayOnTheGaussianSideOfTheAsymmetricModel) {
  const std::vector<Vec3> anchors = {Vec3(0, 0, 2)};
  const std::vector<RangeImuEstimator::TimedPose> trajectory = {{0, Pose3(Mat3::Identity(), Vec3(3, 4, 2))}};
  RangeNoiseParams noise;
  const RangeModel asymmetric("asymmetric", noise);
  RangeSample r;
  r.anchor_id = 0;
  r.range_m = 5.0 - 0.15;  // one sigma short
  EXPECT_EQ(classifyRanges({r}, trajectory, anchors, Vec3::Zero(), asymmetric, noise.sigma_m).downweighted, 0u);
  EXPECT_EQ(classifyRanges({r}, {}, anchors, Vec3::Zero(), asymmetric, noise.sigma_m).ranges, 0u) << "no trajectory";
}

TEST(NlosClassification, RangesTheReceiverFlagsCountAsTreatedAsNlos) {
  // A range with a tiny excess the mixture keeps as LOS; the receiver's
  // power gap says NLOS, so the estimator used its NLOS model for it.
  const std::vector<Vec3> anchors = {Vec3(0, 0, 2)};
  const std::vector<RangeImuEstimator::TimedPose> trajectory = {{0, Pose3(Mat3::Identity(), Vec3(3, 4, 2))}};
  RangeNoiseParams noise;
  RangeSample r;
  r.anchor_id = 0;
  r.range_m = 5.05;
  r.rssi_dbm = -80.0;
  r.fp_power_dbm = -92.0;  // 12 dB gap: NLOS by the 6 dB rule
  EXPECT_EQ(classifyRanges({r}, trajectory, anchors, Vec3::Zero(), RangeModel("asymmetric", noise), noise.sigma_m)
                .downweighted,
            1u);
  noise.nlos_power_gap_db = std::numeric_limits<double>::infinity();  // indicator off: the mixture's verdict
  EXPECT_EQ(classifyRanges({r}, trajectory, anchors, Vec3::Zero(), RangeModel("asymmetric", noise), noise.sigma_m)
                .downweighted,
            0u);
}

}  // namespace
}  // namespace rilo
