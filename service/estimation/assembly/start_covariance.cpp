#include "estimation/assembly/start_covariance.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo {

namespace {

/// inflation * C with every direction at least as wide as the floor sigmas (whitened by them).
template <int N>
Eigen::Matrix<double, N, N> conditioned(const Eigen::Matrix<double, N, N>& C, const Eigen::Matrix<double, N, 1>& floor,
                                        double inflation) {
  using Mat = Eigen::Matrix<double, N, N>;
  const Eigen::Matrix<double, N, 1> inv_floor = floor.cwiseInverse();
  const Mat M = inv_floor.asDiagonal() * (0.5 * (C + C.transpose())) * inv_floor.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Mat> eig(M);
  const Eigen::Matrix<double, N, 1> lambda = (inflation * eig.eigenvalues()).cwiseMax(1.0);
  const Mat M_out = eig.eigenvectors() * lambda.asDiagonal() * eig.eigenvectors().transpose();
  const Mat C_out = floor.asDiagonal() * M_out * floor.asDiagonal();
  return 0.5 * (C_out + C_out.transpose());
}

}  // namespace

void StartCovarianceConditioning::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("StartCovarianceConditioning.") + field + " " + rule);
  };
  if (!(inflation >= 1.0) || !std::isfinite(inflation)) fail("inflation", "must be finite and >= 1");
  if (!pose_floor_sigmas.allFinite() || !(pose_floor_sigmas.minCoeff() > 0.0)) fail("pose_floor_sigmas", "must be finite and > 0");
  if (!std::isfinite(velocity_floor_sigma_m_s) || !(velocity_floor_sigma_m_s > 0.0)) {
    fail("velocity_floor_sigma_m_s", "must be finite and > 0");
  }
  if (!bias_floor_sigmas.allFinite() || !(bias_floor_sigmas.minCoeff() > 0.0)) fail("bias_floor_sigmas", "must be finite and > 0");
}

std::optional<StartCovariance> conditionStartCovariance(const Mat6& pose, const Mat3& velocity, const Mat6& bias,
                                                        const StartCovarianceConditioning& params,
                                                        double variance_factor) {
  params.validate();
  if (!(variance_factor >= 1.0) || !std::isfinite(variance_factor)) {
    throw std::invalid_argument("conditionStartCovariance: variance_factor must be finite and >= 1");
  }
  if (!pose.allFinite() || !velocity.allFinite() || !bias.allFinite()) return std::nullopt;
  const double k = variance_factor * params.inflation;
  StartCovariance out;
  out.pose = conditioned<6>(pose, params.pose_floor_sigmas, k);
  out.velocity = conditioned<3>(velocity, Vec3(Vec3::Constant(params.velocity_floor_sigma_m_s)), k);
  out.bias = conditioned<6>(bias, params.bias_floor_sigmas, k);
  return out;
}

double residualScale(std::span<double> abs_residuals) {
  if (abs_residuals.empty()) return std::numeric_limits<double>::quiet_NaN();
  // 1.4826 = 1 / Phi^-1(3/4): the median of |r| of a unit normal.
  const auto mid = abs_residuals.begin() + static_cast<std::ptrdiff_t>(abs_residuals.size() / 2);
  std::nth_element(abs_residuals.begin(), mid, abs_residuals.end());
  double median = *mid;
  if (abs_residuals.size() % 2 == 0) median = 0.5 * (median + *std::max_element(abs_residuals.begin(), mid));
  return 1.4826 * median;
}

}  // namespace rilo
