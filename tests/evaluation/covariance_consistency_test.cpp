// Whether a published covariance covers the error (evaluation/
// covariance_consistency.h): errors drawn from the covariance itself keep 95 %
// inside and a NEES of 3; a covariance that claims half the spread keeps
// what the chi-square distribution says; unusable covariances and poses
// without ground truth stay out of every figure.
#include "evaluation/covariance_consistency.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

namespace rilo {
namespace {

constexpr std::int64_t kStepNs = 10'000'000;

/// Ground truth every 10 ms on a straight walk.
std::vector<GroundTruthPose> truthOf(std::size_t n) {
  std::vector<GroundTruthPose> truth(n);
  for (std::size_t k = 0; k < n; ++k) {
    truth[k].t_ns = static_cast<std::int64_t>(k) * kStepNs;
    truth[k].p_w_b = Vec3(0.012 * static_cast<double>(k), 3.0, 1.4);
  }
  return truth;
}

/// Published positions off the truth by errors drawn from N(0, drawn_from),
/// claiming `claimed`.
std::vector<TimedPositionCovariance> publish(const std::vector<GroundTruthPose>& truth, const Mat3& drawn_from,
                                             const Mat3& claimed, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  const Mat3 L = drawn_from.llt().matrixL();
  std::vector<TimedPositionCovariance> out;
  for (const GroundTruthPose& g : truth) {
    const Vec3 e = L * Vec3(n01(rng), n01(rng), n01(rng));
    out.push_back({g.t_ns, g.p_w_b + e, claimed, false});
  }
  return out;
}

Mat3 anisotropic() {
  Mat3 P;
  P << 0.04, 0.012, 0.003, 0.012, 0.01, -0.002, 0.003, -0.002, 0.09;
  return P;
}

TEST(CovarianceConsistency, ErrorsDrawnFromTheCovarianceKeepNinetyFivePercentInside) {
  const std::vector<GroundTruthPose> truth = truthOf(20000);
  const Mat3 P = anisotropic();
  const CovarianceConsistency c = covarianceConsistency(publish(truth, P, P, 7), truth, 1'000'000);
  EXPECT_EQ(c.poses, truth.size());
  EXPECT_EQ(c.not_positive_definite, 0u);
  EXPECT_NEAR(c.horizontal_in_95, 0.95, 0.01);
  EXPECT_NEAR(c.vertical_in_95, 0.95, 0.01);
  EXPECT_NEAR(c.nees_mean, 3.0, 0.08);
  EXPECT_NEAR(c.sigma_horizontal_m, std::sqrt(0.025), 1e-12);
  EXPECT_NEAR(c.sigma_vertical_m, 0.3, 1e-12);
  EXPECT_NEAR(c.error_horizontal_m, std::sqrt(0.025), 0.003);
  EXPECT_NEAR(c.error_vertical_m, 0.3, 0.005);
}

TEST(CovarianceConsistency, ACovarianceThatClaimsHalfTheSpreadKeepsWhatTheChiSquareSays) {
  const std::vector<GroundTruthPose> truth = truthOf(20000);
  const Mat3 P = anisotropic();
  // Claimed sigma half the true one: e^T P^-1 e is 4 chi^2, so inside means
  // chi^2_2 <= 5.991 / 4 (1 - exp(-0.749) = 0.527) and |z| <= 0.98 (0.673).
  const CovarianceConsistency c = covarianceConsistency(publish(truth, P, P / 4.0, 11), truth, 1'000'000);
  EXPECT_NEAR(c.horizontal_in_95, 1.0 - std::exp(-5.991464547107979 / 8.0), 0.01);
  EXPECT_NEAR(c.vertical_in_95, std::erf(1.959963984540054 / 2.0 / std::sqrt(2.0)), 0.01);
  EXPECT_NEAR(c.nees_mean, 12.0, 0.3);
  EXPECT_NEAR(c.error_horizontal_m / c.sigma_horizontal_m, 2.0, 0.03);
}

TEST(CovarianceConsistency, UnusableCovariancesAndPosesWithoutTruthStayOut) {
  const std::vector<GroundTruthPose> truth = truthOf(100);
  std::vector<TimedPositionCovariance> published = publish(truth, Mat3::Identity() * 0.01, Mat3::Identity() * 0.01, 3);
  Mat3 indefinite = Mat3::Identity() * 0.01;
  indefinite(2, 2) = -0.01;
  Mat3 asymmetric = Mat3::Identity() * 0.01;
  asymmetric(0, 1) = 0.005;
  Mat3 not_finite = Mat3::Identity() * 0.01;
  not_finite(1, 1) = std::numeric_limits<double>::infinity();
  published[3].cov_p_w = indefinite;
  published[4].cov_p_w = asymmetric;
  published[5].cov_p_w = not_finite;
  published[6].cov_p_w.setZero();
  // Far beyond the truth's end (1 s later): no partner within 5 ms.
  published.push_back({truth.back().t_ns + 1'000'000'000, Vec3(100.0, 0.0, 0.0), Mat3::Identity() * 1e-6, true});
  const CovarianceConsistency c = covarianceConsistency(published, truth, 5'000'000);
  EXPECT_EQ(c.not_positive_definite, 4u);
  EXPECT_EQ(c.poses, 96u);
  EXPECT_GT(c.horizontal_in_95, 0.8);  // the far pose, 100 m off claiming 1 mm, is not among them

  EXPECT_EQ(covarianceConsistency({}, truth, 5'000'000).poses, 0u);
  EXPECT_EQ(covarianceConsistency(published, {}, 5'000'000).poses, 0u);
  EXPECT_THROW(covarianceConsistency(published, truth, -1), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
