// RangeTrustMonitor: rejected_ranges counts unknown anchors and the ranges the
// range model's robust loss down-weights below 0.5 at the newest state.
#include "rilod/range_trust_monitor.h"

#include <gtest/gtest.h>

#include "estimation/noise/noise_model_factory.h"
#include "math/so3.h"

namespace rilo {
namespace {

const std::vector<Vec3> kAnchors = {Vec3(0, 0, 2.5), Vec3(6, 0, 1.0), Vec3(6, 5, 2.5), Vec3(0, 5, 1.0)};
constexpr std::int64_t kMs = 1'000'000;

RangeImuGraphParams graphParams(const std::string& loss = "asymmetric") {
  RangeImuGraphParams p;
  p.range_loss = loss;
  p.range_noise.sigma_m = 0.1;
  p.p_b_tag = Vec3(0.06, 0.0, 0.10);
  p.same_state_window_ns = 5 * kMs;
  return p;
}

StateEstimate stateAt(std::int64_t t_ns) {
  StateEstimate s;
  s.t_ns = t_ns;
  s.T_w_b = Pose3(so3::exp(Vec3(0.0, 0.0, 0.7)), Vec3(2.0, 1.5, 1.2));
  return s;
}

/// The range the state predicts to `anchor`, plus `excess_m`.
RangeSample rangeFrom(const StateEstimate& s, std::uint32_t anchor, double excess_m, std::int64_t t_ns) {
  const Vec3 p_w_tag = s.T_w_b.p + s.T_w_b.R * graphParams().p_b_tag;
  RangeSample r;
  r.t_ns = t_ns;
  r.anchor_id = anchor;
  r.range_m = (p_w_tag - kAnchors[anchor]).norm() + excess_m;
  return r;
}

TEST(RangeTrustMonitor, WeightIsTheRangeModelsLossAtTheWhitenedResidual) {
  RangeTrustMonitor m(kAnchors, graphParams());
  const StateEstimate s = stateAt(0);
  const auto loss = makeRangeLoss("asymmetric", graphParams().range_noise);
  for (double excess : {-0.3, -0.05, 0.0, 0.05, 0.4, 2.0}) {
    EXPECT_NEAR(m.weight(rangeFrom(s, 1, excess, 0), s.T_w_b), loss->weight(excess / 0.1), 1e-9) << excess;
  }
}

TEST(RangeTrustMonitor, CountsRangesDownWeightedAtTheNewestState) {
  RangeTrustMonitor m(kAnchors, graphParams());
  const StateEstimate s = stateAt(1000 * kMs);
  m.onRange(rangeFrom(s, 0, 0.02, 1000 * kMs));  // LOS-like
  m.onRange(rangeFrom(s, 1, 1.50, 1002 * kMs));  // 15 sigma long: NLOS side
  m.onRange(rangeFrom(s, 2, 0.00, 1004 * kMs));
  m.onRange(rangeFrom(s, 3, 2.00, 1030 * kMs));  // the next state's: waits
  EXPECT_EQ(m.judge(s), 1u);
  EXPECT_EQ(m.rejected(), 1u);
  EXPECT_EQ(m.judged(), 3u);
  const StateEstimate next = stateAt(1030 * kMs);
  EXPECT_EQ(m.judge(next), 1u);
  EXPECT_EQ(m.rejected(), 2u);
  EXPECT_EQ(m.judged(), 4u);
}

// What rt/rilo/ranges publishes: each judged range with its prediction and weight.
TEST(RangeTrustMonitor, TheLastJudgedRangesKeepTheirPredictionAndWeight) {
  RangeTrustMonitor m(kAnchors, graphParams());
  const StateEstimate s = stateAt(1000 * kMs);
  const RangeSample los = rangeFrom(s, 0, 0.02, 1000 * kMs);
  const RangeSample nlos = rangeFrom(s, 1, 1.50, 1002 * kMs);
  m.onRange(los);
  m.onRange(nlos);
  m.onRange(rangeFrom(s, 3, 2.00, 1030 * kMs));  // the next state's: not in this epoch
  m.judge(s);
  ASSERT_EQ(m.lastVerdicts().size(), 2u);
  const RangeVerdict& a = m.lastVerdicts()[0];
  const RangeVerdict& b = m.lastVerdicts()[1];
  EXPECT_EQ(a.anchor_id, 0u);
  EXPECT_EQ(a.range_m, los.range_m);
  EXPECT_NEAR(a.range_m - a.predicted_m, 0.02, 1e-9);
  EXPECT_NEAR(a.weight, m.weight(los, s.T_w_b), 1e-12);
  EXPECT_GE(a.weight, RangeTrustMonitor::kTrustedWeight);
  EXPECT_EQ(b.anchor_id, 1u);
  EXPECT_NEAR(b.range_m - b.predicted_m, 1.50, 1e-9);
  EXPECT_LT(b.weight, RangeTrustMonitor::kTrustedWeight);
  m.judge(stateAt(1030 * kMs));
  ASSERT_EQ(m.lastVerdicts().size(), 1u);
  EXPECT_EQ(m.lastVerdicts()[0].anchor_id, 3u);
  m.reset();
  EXPECT_TRUE(m.lastVerdicts().empty());
}

// Ranges of a state's 50 ms (config/rilod.yaml) are judged where the state's
// velocity takes the tag by their time, as their factors predict them.
TEST(RangeTrustMonitor, ALaterRangeOfTheStateIsPredictedWhereTheVelocityTakesTheTag) {
  RangeImuGraphParams p = graphParams();
  p.same_state_window_ns = 50 * kMs;
  RangeTrustMonitor m(kAnchors, p);
  StateEstimate s = stateAt(1000 * kMs);
  s.v_w = Vec3(1.5, 0.0, 0.0);
  StateEstimate moved = s;  // where the tag is 40 ms later
  moved.T_w_b.p += 0.04 * s.v_w;
  m.onRange(rangeFrom(moved, 1, 0.0, 1040 * kMs));
  m.judge(s);
  ASSERT_EQ(m.lastVerdicts().size(), 1u);
  EXPECT_NEAR(m.lastVerdicts()[0].range_m - m.lastVerdicts()[0].predicted_m, 0.0, 1e-9);
  EXPECT_EQ(m.lastVerdicts()[0].t_offset_ns, 40 * kMs) << "published as the range's time after the state's stamp";
}

TEST(RangeTrustMonitor, TheLossDecidesAboutShortRangesToo) {
  RangeTrustMonitor asymmetric(kAnchors, graphParams("asymmetric"));
  RangeTrustMonitor huber(kAnchors, graphParams("huber"));
  const StateEstimate s = stateAt(0);
  const RangeSample short_range = rangeFrom(s, 2, -1.0, 0);
  asymmetric.onRange(short_range);
  huber.onRange(short_range);
  asymmetric.judge(s);
  huber.judge(s);
  EXPECT_EQ(huber.rejected(), 1u);  // |r| = 10 sigma: Huber weight 0.13
  // The asymmetric model's short side is its Gaussian core: the smoother
  // weighs such a range fully, so it is not counted as rejected.
  EXPECT_EQ(asymmetric.rejected(), 0u);
}

TEST(RangeTrustMonitor, UnknownAnchorsCountAtOnceAndOlderRangesGoUnjudged) {
  RangeTrustMonitor m(kAnchors, graphParams());
  RangeSample unknown;
  unknown.anchor_id = 9;
  unknown.range_m = 3.0;
  m.onRange(unknown);
  EXPECT_EQ(m.rejected(), 1u);
  const StateEstimate s = stateAt(2000 * kMs);
  m.onRange(rangeFrom(s, 0, 5.0, 1900 * kMs));  // an older state's, absorbed in the same update
  EXPECT_EQ(m.judge(s), 0u);
  EXPECT_EQ(m.unjudged(), 1u);
  m.onRange(rangeFrom(s, 0, 5.0, 2000 * kMs));
  m.reset();  // tracking lost
  EXPECT_EQ(m.judge(s), 0u);
  EXPECT_EQ(m.judged(), 0u);
}

}  // namespace
}  // namespace rilo
