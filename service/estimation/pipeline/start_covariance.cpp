#include "estimation/pipeline/start_covariance.h"

#include <Eigen/Eigenvalues>
#include <cmath>
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
                                                        const StartCovarianceConditioning& params) {
  params.validate();
  if (!pose.allFinite() || !velocity.allFinite() || !bias.allFinite()) return std::nullopt;
  StartCovariance out;
  out.pose = conditioned<6>(pose, params.pose_floor_sigmas, params.inflation);
  out.velocity = conditioned<3>(velocity, Vec3(Vec3::Constant(params.velocity_floor_sigma_m_s)), params.inflation);
  out.bias = conditioned<6>(bias, params.bias_floor_sigmas, params.inflation);
  return out;
}

}  // namespace rilo
