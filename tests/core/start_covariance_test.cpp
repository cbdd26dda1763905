// The hand-over's start priors (start_covariance.h): conditioning of the
// batch marginals, and that the initializer hands the tracker exactly the
// newest batch state's marginals (checked against an inverse of J^T J
// assembled here from the window's factors), which the graph stream and the
// EKF turn into their start priors / initial covariance.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <cmath>
#include <map>
#include <algorithm>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "estimation/assembly/range_imu_graph_stream.h"
#include "estimation/assembly/start_covariance.h"
#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/init/initializer.h"
#include "estimation/tracking/ekf_estimator.h"
#include "estimation/tracking/hand_over.h"
#include "sim/range_imu_scenario.h"
#include "support/initializer_scenarios.h"
#include "support/online_run.h"

namespace rilo {
namespace {

using testing::movingScenario;
InitializerParams paramsFor(const sim::Scenario& s) { return testing::initializerParamsFor(s); }

template <class M>
double relDiff(const M& a, const M& b) {
  return (a - b).norm() / std::max(1e-300, b.norm());
}

/// Smallest eigenvalue of D^-1 C D^-1.
template <int N>
double minWhitenedEigenvalue(const Eigen::Matrix<double, N, N>& C, const Eigen::Matrix<double, N, 1>& floor) {
  const Eigen::Matrix<double, N, N> M = floor.cwiseInverse().asDiagonal() * C * floor.cwiseInverse().asDiagonal();
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>>(M).eigenvalues().minCoeff();
}

Mat6 randomSpd6(std::uint32_t seed, const Vec6& sigmas) {
  std::srand(seed);
  const Mat6 A = Mat6::Random();
  const Mat6 corr = A * A.transpose() + 0.5 * Mat6::Identity();
  const Vec6 d = corr.diagonal().cwiseSqrt().cwiseInverse();
  return sigmas.asDiagonal() * (d.asDiagonal() * corr * d.asDiagonal()) * sigmas.asDiagonal();
}

/// Batch-like marginals of a well-determined state (random correlations, seeded).
struct Marginals {
  Mat6 pose;
  Mat3 vel;
  Mat6 bias;
};
Marginals wellDeterminedMarginals(std::uint32_t seed) {
  return {randomSpd6(seed, (Vec6() << 0.02, 0.02, 0.05, 0.3, 0.3, 0.4).finished()),
          Vec3(0.1, 0.12, 0.08).cwiseAbs2().asDiagonal(),
          randomSpd6(seed + 1, (Vec6() << 0.05, 0.05, 0.05, 2e-3, 2e-3, 2e-3).finished())};
}

TEST(StartCovariance, WellDeterminedMarginalsAreOnlyInflated) {
  StartCovarianceConditioning c;
  c.inflation = 2.0;
  const auto [pose, vel, bias] = wellDeterminedMarginals(1);
  const std::optional<StartCovariance> out = conditionStartCovariance(pose, vel, bias, c);
  ASSERT_TRUE(out.has_value());
  // Every whitened eigenvalue of 2 C is above 1 here, so nothing is floored.
  ASSERT_GT(minWhitenedEigenvalue<6>(2.0 * pose, c.pose_floor_sigmas), 1.0);
  ASSERT_GT(minWhitenedEigenvalue<6>(2.0 * bias, c.bias_floor_sigmas), 1.0);
  EXPECT_LT(relDiff(out->pose, Mat6(2.0 * pose)), 1e-12);
  EXPECT_LT(relDiff(out->velocity, Mat3(2.0 * vel)), 1e-12);
  EXPECT_LT(relDiff(out->bias, Mat6(2.0 * bias)), 1e-12);
}

TEST(StartCovariance, NearSingularMarginalIsFlooredNotOverConfident) {
  StartCovarianceConditioning c;
  // Rank-deficient pose block: yaw and x fully correlated, y with 1e-12 variance.
  Mat6 pose = Mat6::Zero();
  pose.diagonal() << 1e-4, 1e-4, 4e-3, 0.09, 1e-12, 0.04;
  pose(2, 3) = pose(3, 2) = std::sqrt(4e-3 * 0.09);  // correlation 1: singular
  const Mat3 vel = Mat3::Zero();                     // no information at all about its spread: floor
  Mat6 bias = Mat6::Identity() * 1e-14;
  const std::optional<StartCovariance> out = conditionStartCovariance(pose, vel, bias, c);
  ASSERT_TRUE(out.has_value());
  EXPECT_GE(minWhitenedEigenvalue<6>(out->pose, c.pose_floor_sigmas), 1.0 - 1e-9);
  EXPECT_GE(minWhitenedEigenvalue<3>(out->velocity, Vec3(Vec3::Constant(c.velocity_floor_sigma_m_s))), 1.0 - 1e-9);
  EXPECT_GE(minWhitenedEigenvalue<6>(out->bias, c.bias_floor_sigmas), 1.0 - 1e-9);
  // Positive definite: usable as a prior (the factor checks it too).
  EXPECT_NO_THROW(SqrtInformation<6>::fromCovariance(out->pose));
  EXPECT_NO_THROW(SqrtInformation<3>::fromCovariance(out->velocity));
  // The well-determined directions keep their inflated size: yaw, roll.
  EXPECT_GE(out->pose(2, 2), 2.0 * 4e-3);
  EXPECT_NEAR(out->pose(2, 2), 2.0 * 4e-3, 0.01 * 2.0 * 4e-3);  // + the floored x-yaw direction's share
  EXPECT_NEAR(out->pose(0, 0), 2.0 * 1e-4, 1e-9);
  // A direction below its floor: exactly the floor.
  EXPECT_NEAR(out->velocity(0, 0), c.velocity_floor_sigma_m_s * c.velocity_floor_sigma_m_s, 1e-15);
}

TEST(StartCovariance, NonFiniteMarginalGivesNoneAndBadParamsThrow) {
  Mat6 pose = Mat6::Identity();
  pose(1, 1) = std::nan("");
  EXPECT_FALSE(conditionStartCovariance(pose, Mat3::Identity(), Mat6::Identity()).has_value());
  StartCovarianceConditioning c;
  c.inflation = 0.5;
  EXPECT_THROW(conditionStartCovariance(Mat6::Identity(), Mat3::Identity(), Mat6::Identity(), c), std::invalid_argument);
  c = StartCovarianceConditioning();
  c.bias_floor_sigmas(4) = 0.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  for (double bad : {0.5, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(conditionStartCovariance(Mat6::Identity(), Mat3::Identity(), Mat6::Identity(), {}, bad),
                 std::invalid_argument)
        << bad;
  }
}

TEST(StartCovariance, VarianceFactorScalesBeforeInflationAndFloors) {
  StartCovarianceConditioning c;
  c.inflation = 2.0;
  const auto [pose, vel, bias] = wellDeterminedMarginals(3);
  const std::optional<StartCovariance> scaled = conditionStartCovariance(pose, vel, bias, c, 9.0);
  const std::optional<StartCovariance> by_hand = conditionStartCovariance(9.0 * pose, 9.0 * vel, 9.0 * bias, c);
  ASSERT_TRUE(scaled && by_hand);
  EXPECT_LT(relDiff(scaled->pose, by_hand->pose), 1e-12);
  EXPECT_LT(relDiff(scaled->velocity, by_hand->velocity), 1e-12);
  EXPECT_LT(relDiff(scaled->bias, by_hand->bias), 1e-12);
  EXPECT_LT(relDiff(scaled->pose, Mat6(18.0 * pose)), 1e-12);  // nothing floored: 9 x 2 x C
  // A tiny marginal stays at its floor whatever the factor.
  const std::optional<StartCovariance> tiny = conditionStartCovariance(1e-12 * pose, 1e-12 * vel, 1e-12 * bias, c, 4.0);
  ASSERT_TRUE(tiny.has_value());
  EXPECT_NEAR(tiny->velocity(0, 0), c.velocity_floor_sigma_m_s * c.velocity_floor_sigma_m_s, 1e-12);
}

TEST(ResidualScale, IsOneForUnitNormalResidualsAndGrowsWithNoiseAndBias) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  std::vector<double> unit(20001), wide(20001), biased(20001);
  for (std::size_t i = 0; i < unit.size(); ++i) {
    const double r = n01(rng);
    unit[i] = std::abs(r);
    wide[i] = std::abs(3.0 * r);
    biased[i] = std::abs(r + 2.0);  // a shared offset (NLOS excess on every link) counts as error
  }
  EXPECT_NEAR(residualScale(unit), 1.0, 0.03);
  EXPECT_NEAR(residualScale(wide), 3.0, 0.09);
  // median |N(2, 1)| = 2.0 (symmetric about 2, P(r < 0) tiny): scale 1.4826 x 2.
  EXPECT_NEAR(residualScale(biased), 1.4826 * 2.0, 0.05);
  // Exact on small sets: odd and even counts.
  std::vector<double> odd{3.0, 0.5, 1.0};
  EXPECT_DOUBLE_EQ(residualScale(odd), 1.4826 * 1.0);
  std::vector<double> even{4.0, 1.0, 2.0, 0.0};
  EXPECT_DOUBLE_EQ(residualScale(even), 1.4826 * 1.5);
  std::vector<double> none;
  EXPECT_TRUE(std::isnan(residualScale(none)));
}

// ---------------------------------------------------------------------------
// The hand-over.

/// Marginal covariances of `keys` at `values`: columns of the inverse of J^T J
/// (robust-weighted, as the batch's Gauss-Newton Hessian) over every variable
/// of the graph, assembled here from the factors and solved by a sparse LDL^T.
std::map<Key, Eigen::MatrixXd> sparseMarginals(const FactorGraph& graph, const Values& values,
                                               const std::vector<Key>& keys) {
  std::map<Key, int> offset;
  int n = 0;
  for (const FactorPtr& f : graph) {
    for (Key k : f->keys()) {
      if (offset.emplace(k, n).second) n += values.dim(k);
    }
  }
  std::vector<Eigen::Triplet<double>> triplets;
  Residual r;
  Jacobians J;
  for (const FactorPtr& f : graph) {
    f->linearize(values, r, J);
    const std::vector<Key>& fk = f->keys();
    for (std::size_t a = 0; a < fk.size(); ++a) {
      for (std::size_t b = 0; b < fk.size(); ++b) {
        const Eigen::MatrixXd block = J[a].transpose() * J[b];
        for (Eigen::Index i = 0; i < block.rows(); ++i) {
          for (Eigen::Index j = 0; j < block.cols(); ++j) {
            triplets.emplace_back(offset.at(fk[a]) + static_cast<int>(i), offset.at(fk[b]) + static_cast<int>(j), block(i, j));
          }
        }
      }
    }
  }
  Eigen::SparseMatrix<double> H(n, n);
  H.setFromTriplets(triplets.begin(), triplets.end());  // duplicates are summed
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  std::map<Key, Eigen::MatrixXd> out;
  for (Key k : keys) {
    const int d = values.dim(k);
    Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(n, d);
    unit.block(offset.at(k), 0, d, d).setIdentity();
    const Eigen::MatrixXd cols = ldlt.solve(unit);
    out[k] = cols.block(offset.at(k), 0, d, d);
  }
  return out;
}

/// Initializes on a 40 Hz walk (keeping the window) and returns the initializer.
std::unique_ptr<Initializer> initializedOn(const sim::Scenario& s, const InitializerParams& params) {
  auto init = std::make_unique<Initializer>(s.p_w_anchors, params);
  std::size_t i = 0, r = 0;
  while ((i < s.imu.size() || r < s.ranges.size()) && !init->initialized()) {
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      init->addRange(s.ranges[r++]);
    } else {
      init->addImu(s.imu[i++]);
      init->process();
    }
  }
  return init;
}

/// Records what start() was given (the hand-over's wiring).
class StartSpy final : public TrackingEstimator {
 public:
  using TrackingEstimator::start;
  UpdateStats start(std::int64_t t0_ns, const Pose3& T, const Vec3& v, const ImuBias& b,
                    const std::optional<StartCovariance>& covariance) override {
    started_ = true;
    latest_.t_ns = t0_ns;
    latest_.T_w_b = T;
    latest_.v_w = v;
    latest_.bias = b;
    covariance_ = covariance;
    return UpdateStats();
  }
  bool started() const override { return started_; }
  void addImu(const ImuSample&) override {}
  void addMeasurement(const Measurement&) override {}
  void finish() override {}
  int process(std::vector<UpdateStats>* = nullptr) override { return 0; }
  const StateEstimate& latest() const override { return latest_; }
  void drainSmoothed(std::vector<TimedPose>&, bool = false) override {}
  std::optional<CovarianceBlock> latestPoseCovariance() override { return std::nullopt; }
  std::optional<CovarianceBlock> latestVelocityCovariance() override { return std::nullopt; }
  std::uint64_t standstillPriors() const override { return 0; }

  std::optional<StartCovariance> covariance_;

 private:
  bool started_ = false;
  StateEstimate latest_;
};

TEST(StartCovarianceHandOver, StartPriorsAreTheBatchMarginals) {
  const sim::Scenario s = movingScenario(3, 40.0, 30.0);
  const std::unique_ptr<Initializer> init = initializedOn(s, paramsFor(s));
  ASSERT_TRUE(init->initialized()) << init->status().message;
  const InitResult& res = init->result();
  ASSERT_TRUE(res.window.has_value());
  ASSERT_TRUE(res.start_covariance.has_value());

  // Independent marginals: (J^T J)^-1 of the solved window, assembled and solved here.
  const std::uint64_t i = res.state.index;
  const Key x = sym::X(i), v = sym::V(i), b = sym::B(i);
  const std::map<Key, Eigen::MatrixXd> m = sparseMarginals(res.window->graph.graph, res.window->values, {x, v, b});
  EXPECT_LT(relDiff(Mat6(res.pose_covariance), Mat6(m.at(x))), 1e-5);
  // Scaled by the batch's residual scale, clamped (max_hand_over_residual_scale).
  const double s_res = std::clamp(res.residual_scale, 1.0, init->params().max_hand_over_residual_scale);
  const std::optional<StartCovariance> expected = conditionStartCovariance(
      Mat6(m.at(x)), Mat3(m.at(v)), Mat6(m.at(b)), init->params().hand_over_conditioning, s_res * s_res);
  ASSERT_TRUE(expected.has_value());
  EXPECT_LT(relDiff(res.start_covariance->pose, expected->pose), 1e-5);
  EXPECT_LT(relDiff(res.start_covariance->velocity, expected->velocity), 1e-5);
  EXPECT_LT(relDiff(res.start_covariance->bias, expected->bias), 1e-5);
  // Never tighter than the inflated marginal (the floor only widens), and at
  // 40 Hz far tighter than the loose defaults the tracker used to get (1 m).
  const double k = init->params().hand_over_conditioning.inflation * s_res * s_res;
  const Mat6 widened = expected->pose - k * Mat6(m.at(x));
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat6>(widened).eigenvalues().minCoeff(), -1e-12 * expected->pose.norm());
  const Mat3 cov_p = res.start_covariance->pose.bottomRightCorner<3, 3>();
  EXPECT_LT(cov_p.trace(), 0.3);  // a tenth of the loose defaults' 3 m^2
  EXPECT_GT(cov_p.trace(), k * m.at(x).bottomRightCorner(3, 3).trace() * (1.0 - 1e-9));

  // handOver passes it on.
  StartSpy spy;
  handOver(*init, spy);
  ASSERT_TRUE(spy.covariance_.has_value());
  EXPECT_EQ(spy.covariance_->pose, res.start_covariance->pose);
  EXPECT_EQ(spy.covariance_->velocity, res.start_covariance->velocity);
  EXPECT_EQ(spy.covariance_->bias, res.start_covariance->bias);
  EXPECT_EQ(spy.latest().t_ns, res.state.t_ns);

}

TEST(StartCovarianceHandOver, DataNoisierThanNominalWidenTheStartPriorsByTheResidualScale) {
  const sim::Scenario s = movingScenario(3, 40.0, 30.0);
  InitializerParams p = paramsFor(s);
  p.graph.range_noise.sigma_m = s.params.range_sigma_m / 2.0;  // the ranges are 2x noisier than assumed
  const std::unique_ptr<Initializer> init = initializedOn(s, p);
  ASSERT_TRUE(init->initialized()) << init->status().message;
  const InitResult& res = init->result();
  ASSERT_TRUE(res.window && res.start_covariance);

  // The scale, recomputed from the window's range factors (found by type, not by the graph's layout).
  std::vector<double> abs_r;
  for (const auto& f : res.window->graph.graph) {
    if (!dynamic_cast<const RangeFactor*>(f.get())) continue;
    Residual r;
    f->evaluate(res.window->values, r, nullptr);
    abs_r.push_back(std::abs(r(0)));
  }
  ASSERT_EQ(abs_r.size(), res.window->graph.range_factors);
  EXPECT_DOUBLE_EQ(res.residual_scale, residualScale(abs_r));
  EXPECT_GT(res.residual_scale, 1.8);  // ~2 from the noise, more from the NLOS excess

  // The same solve without the scaling: same state, start priors s^2 tighter (the floors are far below here).
  InitializerParams p_off = p;
  p_off.max_hand_over_residual_scale = 1.0;
  const std::unique_ptr<Initializer> off = initializedOn(s, p_off);
  ASSERT_TRUE(off->initialized()) << off->status().message;
  ASSERT_TRUE(off->result().start_covariance.has_value());
  EXPECT_EQ(off->result().state.t_ns, res.state.t_ns);
  EXPECT_LT((off->result().state.T_w_b.p - res.state.T_w_b.p).norm(), 1e-9);
  const double s_res = std::min(res.residual_scale, p.max_hand_over_residual_scale);
  const double ratio_p = res.start_covariance->pose.bottomRightCorner<3, 3>().trace() /
                         off->result().start_covariance->pose.bottomRightCorner<3, 3>().trace();
  const double ratio_v = res.start_covariance->velocity.trace() / off->result().start_covariance->velocity.trace();
  EXPECT_NEAR(ratio_p, s_res * s_res, 0.05 * s_res * s_res);
  EXPECT_NEAR(ratio_v, s_res * s_res, 0.05 * s_res * s_res);
}

TEST(StartCovarianceHandOver, OffHandsOverNoCovariance) {
  const sim::Scenario s = movingScenario(3, 40.0, 30.0);
  InitializerParams off = paramsFor(s);
  off.hand_over_covariance = false;
  const std::unique_ptr<Initializer> init = initializedOn(s, off);
  ASSERT_TRUE(init->initialized()) << init->status().message;
  EXPECT_FALSE(init->result().start_covariance.has_value());
  StartSpy spy;
  handOver(*init, spy);
  EXPECT_TRUE(spy.started());
  EXPECT_FALSE(spy.covariance_.has_value());
}

TEST(StartCovarianceHandOver, StreamPriorsAndEkfCovarianceAreTheGivenBlocks) {
  StartCovariance c;
  c.pose = randomSpd6(7, (Vec6() << 0.01, 0.01, 0.04, 0.2, 0.25, 0.3).finished());
  c.velocity = Vec3(0.05, 0.06, 0.03).cwiseAbs2().asDiagonal();
  c.velocity(0, 1) = c.velocity(1, 0) = 0.5 * 0.05 * 0.06;
  c.bias = randomSpd6(8, (Vec6() << 0.03, 0.03, 0.03, 1e-3, 1e-3, 1e-3).finished());
  const std::vector<Vec3> anchors = {Vec3(0, 0, 2.5), Vec3(8, 0, 2.5), Vec3(8, 6, 2.5), Vec3(0, 6, 2.5)};
  const Pose3 T0(so3::exp(Vec3(0.05, -0.02, 1.1)), Vec3(3.0, 2.0, 1.2));
  const Vec3 v0(0.4, -0.2, 0.0);
  ImuBias b0;
  b0.accel = Vec3(0.02, -0.01, 0.03);

  RangeImuGraphParams gp;
  RangeImuGraphStream stream(anchors, gp);
  const GraphIncrement inc = stream.start(1'000'000'000, T0, v0, b0, c);
  const auto* px = dynamic_cast<const PriorPose3Factor*>(inc.factors[0].get());
  const auto* pv = dynamic_cast<const PriorVec3Factor*>(inc.factors[1].get());
  const auto* pb = dynamic_cast<const PriorBiasFactor*>(inc.factors[2].get());
  ASSERT_TRUE(px && pv && pb);
  EXPECT_LT(relDiff(Mat6(px->sqrtInformation().transpose() * px->sqrtInformation()), Mat6(c.pose.inverse())), 1e-9);
  EXPECT_LT(relDiff(Mat3(pv->sqrtInformation().transpose() * pv->sqrtInformation()), Mat3(c.velocity.inverse())), 1e-9);
  EXPECT_LT(relDiff(Mat6(pb->sqrtInformation().transpose() * pb->sqrtInformation()), Mat6(c.bias.inverse())), 1e-9);
  EXPECT_TRUE(px->prior().R.isApprox(T0.R) && px->prior().p.isApprox(T0.p));

  // Without: the graph's default sigmas, as before.
  RangeImuGraphStream plain(anchors, gp);
  const GraphIncrement inc0 = plain.start(1'000'000'000, T0, v0, b0);
  const auto* px0 = dynamic_cast<const PriorPose3Factor*>(inc0.factors[0].get());
  ASSERT_TRUE(px0);
  EXPECT_LT(relDiff(Vec6(px0->sqrtInformation().diagonal()), Vec6(gp.first_pose_sigmas.cwiseInverse())), 1e-12);

  // A covariance that is not positive definite is refused with the block's name.
  StartCovariance bad = c;
  bad.velocity(2, 2) = -1.0;
  RangeImuGraphStream refused(anchors, gp);
  try {
    refused.start(1'000'000'000, T0, v0, b0, bad);
    ADD_FAILURE() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("velocity"), std::string::npos) << e.what();
  }

  // EKF: the same covariance in the filter's chart (its Pose3-chart view gives the block back).
  EkfEstimator ekf(anchors, gp);
  ekf.start(1'000'000'000, T0, v0, b0, c);
  EXPECT_LT(relDiff(ekf.filter().poseCovarianceInRetractionChart(), c.pose), 1e-9);
  EXPECT_LT(relDiff(Mat3(ekf.filter().covariance().block<3, 3>(6, 6)), c.velocity), 1e-12);
  EXPECT_LT(relDiff(Mat6(ekf.filter().covariance().block<6, 6>(9, 9)), c.bias), 1e-12);
}

}  // namespace
}  // namespace rilo
