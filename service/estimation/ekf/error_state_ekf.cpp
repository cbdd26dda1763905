#include "estimation/ekf/error_state_ekf.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "estimation/ekf/ekf_propagation.h"

namespace rilo {
namespace {

using ekf_index::kAccelBias;
using ekf_index::kGyroBias;
using ekf_index::kPos;
using ekf_index::kTheta;
using ekf_index::kVel;

[[noreturn]] void invalid(const char* where, const char* name, const char* rule) {
  throw std::invalid_argument(std::string("ErrorStateEkf::") + where + ": " + name + " must be " + rule);
}
void requireFinite(double v, const char* where, const char* name) {
  if (!std::isfinite(v)) invalid(where, name, "finite");
}
void requireFinite(const Vec3& v, const char* where, const char* name) {
  if (!v.allFinite()) invalid(where, name, "finite");
}
void requireSigma(double v, const char* where, const char* name) {
  if (!(std::isfinite(v) && v > 0.0)) {
    throw std::invalid_argument(std::string("ErrorStateEkf::") + where + ": " + name +
                                " must be positive and finite, got " + std::to_string(v));
  }
}

void symmetrize(Mat15& P) { P = 0.5 * (P + P.transpose()).eval(); }

using GroupMat6 = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kEkfMaxGroupRows, 6>;
using Group15 = Eigen::Matrix<double, 15, Eigen::Dynamic, 0, 15, kEkfMaxGroupRows>;

}  // namespace

double chiSquare999(int dof) {
  // 99.9 % quantiles of chi-square(dof), dof = 1..16.
  static constexpr double kQuantile[kEkfMaxGroupRows] = {10.828, 13.816, 16.266, 18.467, 20.515, 22.458,
                                                          24.322, 26.124, 27.877, 29.588, 31.264, 32.909,
                                                          34.528, 36.123, 37.697, 39.252};
  if (dof < 1 || dof > kEkfMaxGroupRows) {
    throw std::invalid_argument("chiSquare999: dof must be in [1, " + std::to_string(kEkfMaxGroupRows) + "], got " +
                                std::to_string(dof));
  }
  return kQuantile[dof - 1];
}

EkfGroupMat tdoaGroupCovariance(const EkfTdoaRow* rows, int n, double share) {
  if (n < 0 || n > kEkfMaxGroupRows || (n > 0 && rows == nullptr)) {
    throw std::invalid_argument("tdoaGroupCovariance: n must be in [0, " + std::to_string(kEkfMaxGroupRows) +
                                "] with rows given, got " + std::to_string(n));
  }
  EkfGroupMat R(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      // C_ij = 1/2 sum over common anchors of the sign products (+1 anchor b, -1 anchor a).
      const EkfTdoaRow& ri = rows[i];
      const EkfTdoaRow& rj = rows[j];
      double c = 0.0;
      if (ri.anchor_b == rj.anchor_b) c += 1.0;
      if (ri.anchor_a == rj.anchor_a) c += 1.0;
      if (ri.anchor_b == rj.anchor_a) c -= 1.0;
      if (ri.anchor_a == rj.anchor_b) c -= 1.0;
      const double corr = share * 0.5 * c + (i == j ? 1.0 - share : 0.0);
      R(i, j) = ri.sigma_m * rj.sigma_m * corr;
    }
  }
  return R;
}

ErrorStateEkf::ErrorStateEkf(const EkfParams& params) : params_(params) {
  params_.validate();
  g_w_ = params_.imu.gravityWorld();
  F_.setIdentity();
}

void ErrorStateEkf::initialize(std::int64_t t_ns, const EkfState& state, const Mat15& covariance) {
  if (!state.allFinite()) invalid("initialize", "state", "finite");
  if (!covariance.allFinite()) invalid("initialize", "covariance", "finite");
  const double scale = std::max(1.0, covariance.cwiseAbs().maxCoeff());
  if ((covariance - covariance.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    invalid("initialize", "covariance", "symmetric");
  }
  Eigen::LLT<Mat15> llt(covariance);
  if (llt.info() != Eigen::Success) invalid("initialize", "covariance", "positive definite");

  x_ = state;
  x_.R_w_b = so3::normalize(state.R_w_b);
  P_ = covariance;
  symmetrize(P_);
  t_ns_ = t_ns;
  index_ = 0;
  has_last_sample_ = false;
  gated_share_ = 0.0;
  initialized_ = true;
}

void ErrorStateEkf::initialize(const StateEstimate& estimate, const Mat15& covariance) {
  initialize(estimate.t_ns, EkfState(estimate.T_w_b, estimate.v_w, estimate.bias), covariance);
  index_ = estimate.index;
}

StateEstimate ErrorStateEkf::estimate() const {
  StateEstimate out;
  out.index = index_;
  out.t_ns = t_ns_;
  out.T_w_b = x_.pose();
  out.v_w = x_.v_w;
  out.bias = x_.bias;
  return out;
}

Mat6 ErrorStateEkf::poseCovarianceInRetractionChart() const {
  // [phi; rho] = blockdiag(I, R^T) [dtheta; dp].
  Mat6 J = Mat6::Identity();
  J.block<3, 3>(3, 3) = x_.R_w_b.transpose();
  return J * P_.topLeftCorner<6, 6>() * J.transpose();
}

void ErrorStateEkf::requireInitialized(const char* what) const {
  if (!initialized_) throw std::logic_error(std::string("ErrorStateEkf::") + what + ": call initialize() first");
}

PropagateStatus ErrorStateEkf::propagate(const ImuSample& sample) {
  requireInitialized("propagate");
  requireFinite(sample.gyro_rad_s, "propagate", "sample.gyro_rad_s");
  requireFinite(sample.accel_m_s2, "propagate", "sample.accel_m_s2");
  if (!has_last_sample_ && sample.t_ns == t_ns_) {
    last_sample_ = sample;
    has_last_sample_ = true;
    return PropagateStatus::kFirstSample;
  }
  if (sample.t_ns <= t_ns_) {
    ++counters_.imu_non_positive_dt;
    return PropagateStatus::kNonPositiveDt;
  }
  const double dt_s = 1e-9 * static_cast<double>(sample.t_ns - t_ns_);
  if (dt_s > params_.max_imu_dt_s) {
    ++counters_.imu_gaps;
    return PropagateStatus::kGapTooLarge;
  }
  if (dt_s != bias_dt_cached_s_) {
    bias_phi_ = params_.imu.biasTransition(dt_s);
    bias_q_ = params_.imu.biasDiscreteVariance(dt_s);
    bias_dt_cached_s_ = dt_s;
  }

  const ImuSample& start = has_last_sample_ ? last_sample_ : sample;
  const ImuInterval interval{start.gyro_rad_s, start.accel_m_s2, sample.gyro_rad_s, sample.accel_m_s2, dt_s};
  x_ = integrateImuMidpoint(x_, interval, g_w_, bias_phi_, &F_);
  x_.R_w_b = so3::normalize(x_.R_w_b);  // keep R orthonormal over long runs

  Mat15 FP;
  FP.noalias() = F_ * P_;
  P_.noalias() = FP * F_.transpose();
  addProcessNoise(dt_s);
  symmetrize(P_);

  t_ns_ = sample.t_ns;
  last_sample_ = sample;
  has_last_sample_ = true;
  ++counters_.imu_propagated;
  return PropagateStatus::kPropagated;
}

void ErrorStateEkf::addProcessNoise(double dt_s) {
  const ImuParams& imu = params_.imu;
  const double sg2 = imu.gyro_noise_density * imu.gyro_noise_density;
  const double sa2 = imu.accel_noise_density * imu.accel_noise_density;
  const double si2 = imu.integration_noise_density * imu.integration_noise_density;
  const double dt2 = dt_s * dt_s;
  const double q_pv = 0.5 * sa2 * dt2;
  for (int i = 0; i < 3; ++i) {
    P_(kTheta + i, kTheta + i) += sg2 * dt_s;
    P_(kPos + i, kPos + i) += 0.25 * sa2 * dt2 * dt_s + si2 * dt_s;
    P_(kVel + i, kVel + i) += sa2 * dt_s;
    P_(kPos + i, kVel + i) += q_pv;
    P_(kVel + i, kPos + i) += q_pv;
    P_(kAccelBias + i, kAccelBias + i) += bias_q_(i);
    P_(kGyroBias + i, kGyroBias + i) += bias_q_(3 + i);
  }
  if (params_.velocity_noise_density > 0.0) {  // unmodelled acceleration (EkfParams)
    const double q2 = params_.velocity_noise_density * params_.velocity_noise_density;
    for (int i = 0; i < 3; ++i) {
      P_(kPos + i, kPos + i) += q2 * dt2 * dt_s / 3.0;
      P_(kVel + i, kVel + i) += q2 * dt_s;
      P_(kPos + i, kVel + i) += 0.5 * q2 * dt2;
      P_(kVel + i, kPos + i) += 0.5 * q2 * dt2;
    }
  }
  if (dt_s > imu.gap_threshold_s) {  // dropped samples: the held sample stands for unmeasured motion
    const double ga2 = imu.gap_accel_sigma_m_s2 * imu.gap_accel_sigma_m_s2;
    const double gg2 = imu.gap_gyro_sigma_rad_s * imu.gap_gyro_sigma_rad_s;
    const double gap_pv = 0.5 * ga2 * dt2 * dt_s;
    for (int i = 0; i < 3; ++i) {
      P_(kTheta + i, kTheta + i) += gg2 * dt2;
      P_(kPos + i, kPos + i) += 0.25 * ga2 * dt2 * dt2;
      P_(kVel + i, kVel + i) += ga2 * dt2;
      P_(kPos + i, kVel + i) += gap_pv;
      P_(kVel + i, kPos + i) += gap_pv;
    }
  }
}

template <int M>
EkfUpdateResult ErrorStateEkf::update(const EkfPrediction<M>& pred, const Eigen::Matrix<double, M, 1>& z,
                                      const Eigen::Matrix<double, M, 1>& sigma, const RobustLoss* loss,
                                      double gate_chi2, EkfUpdateCounts& counts) {
  using VecM = Eigen::Matrix<double, M, 1>;
  using MatM = Eigen::Matrix<double, M, M>;
  using Mat15M = Eigen::Matrix<double, 15, M>;

  const VecM y = z - pred.h;
  const auto& H = pred.H;  // M x 6 over [dtheta, dp]; the other columns are zero
  Mat15M PHt;
  PHt.noalias() = P_.leftCols<6>() * H.transpose();
  MatM HPHt;
  HPHt.noalias() = H * PHt.template topRows<6>();
  const VecM R = sigma.cwiseAbs2();

  EkfUpdateResult result;
  result.innovation = y(0);
  MatM S = HPHt;
  S.diagonal() += R;
  const MatM S_inv = S.inverse();  // fixed-size 1x1 / 2x2: closed form
  result.normalized_innovation = y(0) / std::sqrt(S(0, 0));
  result.predicted_variance_m2 = HPHt(0, 0);
  result.mahalanobis_sq = y.dot(S_inv * y);
  if (!(result.mahalanobis_sq <= gate_chi2)) {  // NaN counts as gated
    ++counts.gated;
    result.status = UpdateStatus::kGated;
    return result;
  }

  // Robust re-weighting of the range row (IRLS, see the header).
  VecM R_w = R;
  MatM S_w_inv = S_inv;
  if (loss != nullptr) {
    double w = loss->weight(y(0) / sigma(0));
    for (int it = 1; it < params_.robust_iterations && w >= params_.min_robust_weight; ++it) {
      R_w(0) = R(0) / w;
      MatM S_w = HPHt;
      S_w.diagonal() += R_w;
      const VecM e_post = R_w.cwiseProduct(S_w.inverse() * y);  // z - h(x+) of the linearized model
      w = loss->weight(e_post(0) / sigma(0));
    }
    result.weight = w;
    if (!(w >= params_.min_robust_weight) || w <= 0.0) {
      ++counts.zero_weight;
      result.status = UpdateStatus::kZeroWeight;
      return result;
    }
    R_w(0) = R(0) / w;
    MatM S_w = HPHt;
    S_w.diagonal() += R_w;
    S_w_inv = S_w.inverse();
  }

  Mat15M K;
  K.noalias() = PHt * S_w_inv;
  const Vec15 dx = K * y;

  // Joseph form (I - KH) P (I - KH)^T + K R K^T as two rank-M corrections:
  // X = (I - KH) P = P - K (P H^T)^T, then X (I - KH)^T = X - (X H^T) K^T.
  Mat15 X = P_;
  X.noalias() -= K * PHt.transpose();
  Mat15M XHt;
  XHt.noalias() = X.leftCols<6>() * H.transpose();
  P_ = X;
  P_.noalias() -= XHt * K.transpose();
  P_.noalias() += K * R_w.asDiagonal() * K.transpose();

  injectAndReset(dx);

  ++counts.accepted;
  result.status = UpdateStatus::kAccepted;
  return result;
}

EkfUpdateResult ErrorStateEkf::updateRange(const Vec3& p_w_anchor, const Vec3& p_b_tag, double range_m,
                                           double sigma_m, const RobustLoss* loss) {
  requireInitialized("updateRange");
  requireFinite(p_w_anchor, "updateRange", "p_w_anchor");
  requireFinite(p_b_tag, "updateRange", "p_b_tag");
  requireFinite(range_m, "updateRange", "range_m");
  requireSigma(sigma_m, "updateRange", "sigma_m");
  const Eigen::Matrix<double, 1, 1> z(range_m), sigma(sigma_m);
  return update<1>(predictRange(x_, p_w_anchor, p_b_tag), z, sigma, loss, params_.gate_chi2_1dof,
                   counters_.range);
}

EkfUpdateResult ErrorStateEkf::updateTdoa(const Vec3& p_w_anchor_a, const Vec3& p_w_anchor_b, const Vec3& p_b_tag,
                                          double diff_m, double sigma_m, const RobustLoss* loss) {
  requireInitialized("updateTdoa");
  requireFinite(p_w_anchor_a, "updateTdoa", "p_w_anchor_a");
  requireFinite(p_w_anchor_b, "updateTdoa", "p_w_anchor_b");
  requireFinite(p_b_tag, "updateTdoa", "p_b_tag");
  requireFinite(diff_m, "updateTdoa", "diff_m");
  requireSigma(sigma_m, "updateTdoa", "sigma_m");
  if (p_w_anchor_a == p_w_anchor_b) invalid("updateTdoa", "p_w_anchor_a and p_w_anchor_b", "different");
  const Eigen::Matrix<double, 1, 1> z(diff_m), sigma(sigma_m);
  return update<1>(predictTdoa(x_, p_w_anchor_a, p_w_anchor_b, p_b_tag), z, sigma, loss, params_.gate_chi2_1dof,
                   counters_.tdoa);
}

EkfGroupResult ErrorStateEkf::updateTdoaGroup(const EkfTdoaRow* rows, int n, const Vec3& p_b_tag,
                                             const RobustLoss* loss) {
  requireInitialized("updateTdoaGroup");
  if (n < 0 || n > kEkfMaxGroupRows || (n > 0 && rows == nullptr)) {
    throw std::invalid_argument("ErrorStateEkf::updateTdoaGroup: n must be in [0, " +
                                std::to_string(kEkfMaxGroupRows) + "] with rows given, got " + std::to_string(n));
  }
  requireFinite(p_b_tag, "updateTdoaGroup", "p_b_tag");
  for (int i = 0; i < n; ++i) {
    requireFinite(rows[i].p_w_anchor_a, "updateTdoaGroup", "rows[i].p_w_anchor_a");
    requireFinite(rows[i].p_w_anchor_b, "updateTdoaGroup", "rows[i].p_w_anchor_b");
    requireFinite(rows[i].diff_m, "updateTdoaGroup", "rows[i].diff_m");
    requireSigma(rows[i].sigma_m, "updateTdoaGroup", "rows[i].sigma_m");
    if (rows[i].p_w_anchor_a == rows[i].p_w_anchor_b || rows[i].anchor_a == rows[i].anchor_b) {
      invalid("updateTdoaGroup", "rows[i] anchors a and b", "different");
    }
  }
  EkfGroupResult res;
  res.rows = n;
  if (n == 0) return res;
  // Gate recovery (EkfParams::recovery_gated_share): decided on the groups before this one.
  const bool recovering = gated_share_ > params_.recovery_gated_share;

  // 1. Prior innovations and their covariance.
  EkfGroupVec y(n);
  GroupMat6 H(n, 6);
  for (int i = 0; i < n; ++i) {
    const EkfPrediction<1> pred = predictTdoa(x_, rows[i].p_w_anchor_a, rows[i].p_w_anchor_b, p_b_tag);
    y(i) = rows[i].diff_m - pred.h(0);
    H.row(i) = pred.H;
  }
  const EkfGroupMat R = tdoaGroupCovariance(rows, n, params_.tdoa_path_share);
  const Mat6 P66 = P_.topLeftCorner<6, 6>();
  const EkfGroupMat S_all = H * P66 * H.transpose() + R;
  for (int i = 0; i < n; ++i) {
    res.status[i] = UpdateStatus::kAccepted;
    res.innovation[i] = y(i);
    res.predicted_variance_m2[i] = S_all(i, i) - R(i, i);
    res.weight[i] = 1.0;
  }

  // 2. Gate on the whole group; drop the worst row until the rest passes.
  int idx[kEkfMaxGroupRows];
  int m = n;
  for (int i = 0; i < n; ++i) idx[i] = i;
  while (m > 0) {
    EkfGroupMat S(m, m);
    EkfGroupVec ya(m);
    for (int a = 0; a < m; ++a) {
      ya(a) = y(idx[a]);
      for (int b = 0; b < m; ++b) S(a, b) = S_all(idx[a], idx[b]);
    }
    const Eigen::LLT<EkfGroupMat> llt(S);
    const double nis = llt.info() == Eigen::Success ? ya.dot(llt.solve(ya)) : std::numeric_limits<double>::quiet_NaN();
    if (nis <= chiSquare999(m) * params_.gate_group_scale) {  // NaN fails
      res.mahalanobis_sq = nis;
      break;
    }
    int worst = 0;
    double worst_z = -1.0;
    for (int a = 0; a < m; ++a) {
      const double z = std::abs(ya(a)) / std::sqrt(S(a, a));
      if (!(z <= worst_z)) {  // NaN counts as worst
        worst_z = z;
        worst = a;
      }
    }
    res.status[idx[worst]] = UpdateStatus::kGated;
    for (int a = worst; a + 1 < m; ++a) idx[a] = idx[a + 1];
    --m;
  }
  bool refused[kEkfMaxGroupRows] = {};
  if (recovering && m < n) {
    // The rows the gate refused go to the robust update all the same.
    for (int i = 0; i < n; ++i) {
      refused[i] = res.status[i] == UpdateStatus::kGated;
      idx[i] = i;
      res.status[i] = UpdateStatus::kAccepted;
    }
    m = n;
  }
  res.gated = n - m;
  counters_.tdoa.gated += static_cast<std::uint64_t>(n - m);
  // Average of the refused share; a recovered group refused none, so the
  // gate closes again unless the next groups are refused too.
  gated_share_ += (static_cast<double>(n - m) / static_cast<double>(n) - gated_share_) / params_.recovery_window_groups;
  if (m == 0) return res;

  // 3. Iterated, re-weighted update over the m rows that passed.
  EkfGroupMat Ra(m, m);
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b < m; ++b) Ra(a, b) = R(idx[a], idx[b]);
  }
  Vec15 d = Vec15::Zero();
  Group15 K;
  GroupMat6 Hu;
  EkfGroupMat Rw;
  int used[kEkfMaxGroupRows];
  int u = 0;
  for (int it = 0; it < params_.group_iterations; ++it) {
    const EkfState xj = it == 0 ? x_ : x_.retract(d);
    EkfGroupVec r(m);
    GroupMat6 Hj(m, 6);
    double w[kEkfMaxGroupRows];
    u = 0;
    for (int a = 0; a < m; ++a) {
      const EkfTdoaRow& row = rows[idx[a]];
      const EkfPrediction<1> pred = predictTdoa(xj, row.p_w_anchor_a, row.p_w_anchor_b, p_b_tag);
      r(a) = row.diff_m - pred.h(0);
      Hj.row(a) = pred.H;
      w[a] = loss != nullptr ? loss->weight(r(a) / row.sigma_m) : 1.0;
      res.weight[idx[a]] = w[a];
      if (w[a] >= params_.min_robust_weight && w[a] > 0.0) used[u++] = a;
    }
    if (u == 0) break;
    EkfGroupVec ru(u);
    Hu.resize(u, 6);
    Rw.resize(u, u);
    for (int a = 0; a < u; ++a) {
      ru(a) = r(used[a]) + Hj.row(used[a]).dot(d.head<6>());
      Hu.row(a) = Hj.row(used[a]);
      for (int b = 0; b < u; ++b) Rw(a, b) = Ra(used[a], used[b]) / std::sqrt(w[used[a]] * w[used[b]]);
    }
    const Group15 PHt = P_.leftCols<6>() * Hu.transpose();
    const EkfGroupMat S = Hu * PHt.topRows<6>() + Rw;
    const Eigen::LLT<EkfGroupMat> llt(S);
    K = llt.solve(PHt.transpose()).transpose();
    const Vec15 d_next = K * ru;
    const double step = (d_next - d).norm();
    d = d_next;
    res.iterations = it + 1;
    if (step < 1e-9) break;
  }
  if (u == 0) {
    for (int a = 0; a < m; ++a) res.status[idx[a]] = UpdateStatus::kZeroWeight;
    res.zero_weight = m;
    counters_.tdoa.zero_weight += static_cast<std::uint64_t>(m);
    return res;
  }
  for (int a = 0; a < m; ++a) {
    bool in_use = false;
    for (int b = 0; b < u; ++b) in_use = in_use || used[b] == a;
    if (!in_use) {
      res.status[idx[a]] = UpdateStatus::kZeroWeight;
      ++res.zero_weight;
    } else if (refused[idx[a]]) {
      ++res.recovered;
    }
  }
  res.accepted = u;
  counters_.tdoa.zero_weight += static_cast<std::uint64_t>(m - u);
  counters_.tdoa.accepted += static_cast<std::uint64_t>(u);
  counters_.tdoa_recovered += static_cast<std::uint64_t>(res.recovered);

  // 4. Joseph form with the last gain (as update<M>), then injection and reset.
  const Group15 PHt = P_.leftCols<6>() * Hu.transpose();
  Mat15 X = P_;
  X.noalias() -= K * PHt.transpose();
  const Group15 XHt = X.leftCols<6>() * Hu.transpose();
  P_ = X;
  P_.noalias() -= XHt * K.transpose();
  P_.noalias() += K * Rw * K.transpose();
  injectAndReset(d);
  return res;
}

bool ErrorStateEkf::applyHeightBand(double z_min_m, double z_max_m, double sigma_m) {
  requireInitialized("applyHeightBand");
  requireSigma(sigma_m, "applyHeightBand", "sigma_m");
  if (!(z_min_m <= z_max_m)) invalid("applyHeightBand", "z_min_m", "<= z_max_m");
  const double z = x_.p_w_b.z();
  if (z >= z_min_m && z <= z_max_m) return false;
  EkfPrediction<1> pred;
  pred.h(0) = z;
  pred.H.setZero();
  pred.H(0, 5) = 1.0;  // d z / d dp_z (dp in world)
  const Eigen::Matrix<double, 1, 1> bound(z < z_min_m ? z_min_m : z_max_m), sigma(sigma_m);
  return update<1>(pred, bound, sigma, nullptr, std::numeric_limits<double>::infinity(), counters_.height_band).status ==
         UpdateStatus::kAccepted;
}

void ErrorStateEkf::applyVerticalSpeedPrior(double sigma_m_s) {
  requireInitialized("applyVerticalSpeedPrior");
  requireSigma(sigma_m_s, "applyVerticalSpeedPrior", "sigma_m_s");
  updateVelocityAxis(2, sigma_m_s * sigma_m_s);
  ++counters_.vertical_speed.accepted;
}

void ErrorStateEkf::applyZeroVelocityPrior(double sigma_m_s) {
  requireInitialized("applyZeroVelocityPrior");
  requireSigma(sigma_m_s, "applyZeroVelocityPrior", "sigma_m_s");
  // With a diagonal noise, three scalar updates in turn are the 3-D update.
  const double r = sigma_m_s * sigma_m_s;
  for (int axis = 0; axis < 3; ++axis) updateVelocityAxis(axis, r);
  ++counters_.zero_velocity.accepted;
}

void ErrorStateEkf::updateVelocityAxis(int axis, double r) {
  // Scalar update of the error state's dv_axis (EkfPrediction covers the pose
  // block only): H = e_v, y = 0 - v, Joseph form, then the usual injection
  // and reset.
  const int k = ekf_index::kVel + axis;
  const Vec15 PHt = P_.col(k);
  const double S = PHt(k) + r;
  const Vec15 K = PHt / S;
  const Vec15 dx = K * (0.0 - x_.v_w(axis));
  Mat15 X = P_;
  X.noalias() -= K * PHt.transpose();  // (I - K H) P
  const Vec15 XHt = X.col(k);
  P_ = X;
  P_.noalias() -= XHt * K.transpose();
  P_.noalias() += r * K * K.transpose();
  injectAndReset(dx);
}

EkfUpdateResult ErrorStateEkf::updateUltrasonic(const Vec3& p_w_anchor, const Vec3& p_b_us, double range_m,
                                                double sigma_m, const std::optional<UltrasonicElevation>& elevation,
                                                const RobustLoss* loss) {
  requireInitialized("updateUltrasonic");
  requireFinite(p_w_anchor, "updateUltrasonic", "p_w_anchor");
  requireFinite(p_b_us, "updateUltrasonic", "p_b_us");
  requireFinite(range_m, "updateUltrasonic", "range_m");
  requireSigma(sigma_m, "updateUltrasonic", "sigma_m");
  const EkfPrediction<2> pred = predictUltrasonic(x_, p_w_anchor, p_b_us);
  if (!elevation) {
    EkfPrediction<1> range_only;
    range_only.h(0) = pred.h(0);
    range_only.H = pred.H.row(0);
    const Eigen::Matrix<double, 1, 1> z(range_m), sigma(sigma_m);
    return update<1>(range_only, z, sigma, loss, params_.gate_chi2_1dof, counters_.ultrasonic);
  }
  requireFinite(elevation->delta_h_m, "updateUltrasonic", "elevation.delta_h_m");
  requireSigma(elevation->sigma_h_m, "updateUltrasonic", "elevation.sigma_h_m");
  const Eigen::Vector2d z(range_m, elevation->delta_h_m);
  const Eigen::Vector2d sigma(sigma_m, elevation->sigma_h_m);
  return update<2>(pred, z, sigma, loss, params_.gate_chi2_2dof, counters_.ultrasonic);
}

void ErrorStateEkf::injectAndReset(const Vec15& dx) {
  // dtheta' = Jr(dtheta_hat) (dtheta - dtheta_hat): the covariance's rotation rows and columns.
  x_ = x_.retract(dx);
  const Mat3 G = so3::rightJacobian(dx.segment<3>(kTheta));
  const Eigen::Matrix<double, 3, 15> top = G * P_.topRows<3>();
  P_.topRows<3>() = top;
  const Eigen::Matrix<double, 15, 3> left = P_.leftCols<3>() * G.transpose();
  P_.leftCols<3>() = left;
  symmetrize(P_);
}

}  // namespace rilo
