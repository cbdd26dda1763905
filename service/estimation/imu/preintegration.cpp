#include "estimation/imu/preintegration.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

inline Mat3 skew(const Vec3& a) {
  Mat3 S;
  S << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return S;
}

// Below this angle (rad) the SO(3) coefficients use their Taylor series.
constexpr double kSeriesAngle = 0.02;

// Exp, Jr, Jr^-1 at theta and d(Jr^-1(theta) w)/dtheta from one sincos.
//   Exp   = I + ea W + eb W^2         W = [theta]x, t = |theta|
//   Jr    = I - eb W + jb W^2
//   Jr^-1 = I + W/2 + ib W^2          ib = 1/t^2 - cot(t/2)/(2t)
//   d(Jr^-1 w)/dtheta = -[w]x/2 + ic u theta^T + ib ((theta.w) I + theta w^T - 2 w theta^T),
//   u = theta x (theta x w), ic = (d ib/dt) / t.
//   Jr^-1 Jr^-T = I + (2 ib - 1/4 - ib^2 t^2) W^2   (W^3 = -t^2 W; exactly symmetric)
struct So3AtTheta {
  Mat3 R, Jr, Jr_inv, dJrinv_w, JJt;
};

inline So3AtTheta so3AtTheta(const Vec3& theta, const Vec3& w) {
  const double t2 = theta.squaredNorm();
  double ea, eb, jb, ib, ic;
  if (t2 < kSeriesAngle * kSeriesAngle) {
    const double t4 = t2 * t2;
    ea = 1.0 - t2 / 6.0 + t4 / 120.0;
    eb = 0.5 - t2 / 24.0 + t4 / 720.0;
    jb = 1.0 / 6.0 - t2 / 120.0 + t4 / 5040.0;
    ib = 1.0 / 12.0 + t2 / 720.0 + t4 / 30240.0;
    ic = 1.0 / 360.0 + t2 / 7560.0 + t4 / 201600.0;
  } else {
    // Half-angle forms: well defined up to t = 2 pi (exclusive).
    const double t = std::sqrt(t2);
    const double s = std::sin(0.5 * t), c = std::cos(0.5 * t);
    const double sin_t = 2.0 * s * c, one_minus_cos = 2.0 * s * s;
    ea = sin_t / t;
    eb = one_minus_cos / t2;
    jb = (t - sin_t) / (t2 * t);
    ib = 1.0 / t2 - c / (2.0 * t * s);
    ic = (t2 + t * sin_t - 4.0 * one_minus_cos) / (2.0 * t2 * t2 * one_minus_cos);
  }
  const Mat3 W = skew(theta);
  const Mat3 W2 = theta * theta.transpose() - t2 * Mat3::Identity();
  So3AtTheta out;
  out.R = Mat3::Identity() + ea * W + eb * W2;
  out.Jr = Mat3::Identity() - eb * W + jb * W2;
  out.Jr_inv = Mat3::Identity() + 0.5 * W + ib * W2;
  out.JJt = Mat3::Identity() + (2.0 * ib - 0.25 - ib * ib * t2) * W2;
  const Vec3 u = theta.cross(theta.cross(w));
  out.dJrinv_w = -0.5 * skew(w) + ic * u * theta.transpose() +
                 ib * (theta.dot(w) * Mat3::Identity() + theta * w.transpose() - 2.0 * w * theta.transpose());
  return out;
}

// M + M^T, exactly symmetric.
inline Mat3 plusTranspose(const Mat3& M) {
  const Mat3 Mt = M.transpose();
  return M + Mt;
}

// Per-sample Jacobians of xi+ (see the header): A = [[T, 0, 0], [dt/2 G, I, dt I], [G, 0, I]],
// B = [0; dt/2 Rd; Rd], C = [Jd; 0; 0], with Rd = R dt and Jd = Jr^-1 dt.
struct StepJacobians {
  Mat3 T, G, Rd, Jd;
  double dt, hdt;
};

// S <- A S A^T, block by block (10 3x3 products instead of 2 dense 9x9 ones).
template <class Sym>
inline void propagate(Sym& S, const StepJacobians& J) {
  const double dt = J.dt, hdt = J.hdt;
  // Y = A S.
  const Mat3 Y_tt = J.T * S.tt, Y_tp = J.T * S.tp, Y_tv = J.T * S.tv;
  const Mat3 W_t = J.G * S.tt, W_p = J.G * S.tp, W_v = J.G * S.tv;
  const Mat3 Y_pt = hdt * W_t + S.tp.transpose() + dt * S.tv.transpose();
  const Mat3 Y_pp = hdt * W_p + S.pp + dt * S.pv.transpose();
  const Mat3 Y_pv = hdt * W_v + S.pv + dt * S.vv;
  const Mat3 Y_vt = W_t + S.tv.transpose();
  const Mat3 Y_vv = W_v + S.vv;
  // S' = Y A^T: (r, theta) = Y_rt T^T; (r, p) = dt/2 K_r + Y_rp + dt Y_rv; (r, v) = K_r + Y_rv; K_r = Y_rt G^T.
  const Mat3 Gt = J.G.transpose();
  const Mat3 K_t = Y_tt * Gt, K_p = Y_pt * Gt, K_v = Y_vt * Gt;
  const Mat3 tt = Y_tt * J.T.transpose();
  S.tt = 0.5 * plusTranspose(tt);  // symmetric up to rounding: make it exact
  S.tp = hdt * K_t + Y_tp + dt * Y_tv;
  S.tv = K_t + Y_tv;
  const Mat3 pp = hdt * K_p + Y_pp + dt * Y_pv;
  S.pp = 0.5 * plusTranspose(pp);
  S.pv = K_p + Y_pv;
  const Mat3 vv = K_v + Y_vv;
  S.vv = 0.5 * plusTranspose(vv);
}

// S += B va B^T + C vg C^T + integration noise, for isotropic input variances
// va, vg (R R^T = I makes the B part diagonal); JJt = Jr^-1 Jr^-T.
template <class Sym>
inline void addInputNoise(Sym& S, const Mat3& JJt, double va, double vg, double vi, double dt) {
  const double dt2 = dt * dt;
  S.tt += (vg * dt2) * JJt;
  S.pp.diagonal().array() += va * dt2 * dt2 * 0.25 + vi * dt;
  S.pv.diagonal().array() += va * dt2 * dt * 0.5;
  S.vv.diagonal().array() += va * dt2;
}

}  // namespace

void PreintegratedImu::SymBlocks::setZero() {
  tt.setZero();
  tp.setZero();
  tv.setZero();
  pp.setZero();
  pv.setZero();
  vv.setZero();
}

Mat9 PreintegratedImu::SymBlocks::full() const {
  Mat9 S;
  S << tt, tp, tv, tp.transpose(), pp, pv, tv.transpose(), pv.transpose(), vv;
  return S;
}

void PreintegratedImu::CrossBlocks::setZero() {
  t_g.setZero();
  p_a.setZero();
  p_g.setZero();
  v_a.setZero();
  v_g.setZero();
}

PreintegratedImu::PreintegratedImu(const ImuParams& params, const ImuBias& bias_hat, CovarianceMode mode)
    : params_(params), mode_(mode) {
  params_.validate();
  accel_var_density_ = params_.accel_noise_density * params_.accel_noise_density;
  gyro_var_density_ = params_.gyro_noise_density * params_.gyro_noise_density;
  integ_var_density_ = params_.integration_noise_density * params_.integration_noise_density;
  reset(bias_hat);
}

void PreintegratedImu::reset(const ImuBias& bias_hat) {
  bias_hat_ = bias_hat;
  dt_s_ = 0.0;
  num_samples_ = 0;
  theta_.setZero();
  p_.setZero();
  v_.setZero();
  J_xi_ba_.setZero();
  J_xi_bg_.setZero();
  cov_.setZero();
  comb_xi_.setZero();
  comb_xi_b_.setZero();
  comb_ba_ = comb_bg_ = 0.0;
}

void PreintegratedImu::integrate(const Vec3& accel_m_s2, const Vec3& gyro_rad_s, double dt_s) {
  if (!(std::isfinite(dt_s) && dt_s > 0.0)) {
    throw std::invalid_argument("PreintegratedImu::integrate: dt_s must be finite and > 0");
  }
  if (!accel_m_s2.allFinite() || !gyro_rad_s.allFinite()) {
    throw std::invalid_argument("PreintegratedImu::integrate: accel_m_s2 and gyro_rad_s must be finite");
  }
  const Vec3 a = accel_m_s2 - bias_hat_.accel;
  const Vec3 w = gyro_rad_s - bias_hat_.gyro;

  const So3AtTheta f = so3AtTheta(theta_, w);
  StepJacobians J;
  J.dt = dt_s;
  J.hdt = 0.5 * dt_s;
  J.T = Mat3::Identity() + dt_s * f.dJrinv_w;      // d theta+ / d theta
  J.G = -(f.R * (skew(a) * f.Jr)) * dt_s;           // d v+ / d theta
  J.Rd = f.R * dt_s;                               // d v+ / d a
  J.Jd = f.Jr_inv * dt_s;                          // d theta+ / d w
  const Mat3& JJt = f.JJt;
  double va = accel_var_density_ / dt_s, vg = gyro_var_density_ / dt_s;  // discrete sample variances
  if (dt_s > params_.gap_threshold_s) {  // dropped samples: unmeasured motion (ImuParams)
    va += params_.gap_accel_sigma_m_s2 * params_.gap_accel_sigma_m_s2;
    vg += params_.gap_gyro_sigma_rad_s * params_.gap_gyro_sigma_rad_s;
  }

  if (hasCovariance()) {
    propagate(cov_, J);
    addInputNoise(cov_, JJt, va, vg, integ_var_density_, dt_s);
  }
  if (hasCombinedCovariance()) {
    // Bias transition over dt (recomputed only when dt changes).
    if (dt_s != bias_dt_cached_) {
      const Vec6 phi = params_.biasTransition(dt_s), q = params_.biasDiscreteVariance(dt_s);
      phi_ba_ = phi(0);
      phi_bg_ = phi(3);
      q_ba_ = q(0);
      q_bg_ = q(3);
      bias_dt_cached_ = dt_s;
    }
    // With X the xi-bias block and Pb the bias block (diag(pa I, pg I)), M = [B C]:
    //   Z = A X;  P+ = A P A^T - (M Z^T + Z M^T) + M Pb M^T + white noise;
    //   X+ = (Z - M Pb) Phi;  Pb+ = Phi Pb Phi + Qb.
    // Block form, using X_theta,a = 0 (theta does not depend on the accel bias).
    CrossBlocks& X = comb_xi_b_;
    const double dt = dt_s, hdt = J.hdt, pa = comb_ba_, pg = comb_bg_;
    const Mat3 GX = J.G * X.t_g;
    const Mat3 Z_tg = J.T * X.t_g;
    const Mat3 Z_pa = X.p_a + dt * X.v_a;
    const Mat3 Z_pg = hdt * GX + X.p_g + dt * X.v_g;
    const Mat3 Z_va = X.v_a;
    const Mat3 Z_vg = GX + X.v_g;
    // N = M Z^T by blocks (rows theta: Jd Z_rg^T; rows p, v: hdt Rd Z_ra^T, Rd Z_ra^T; Z_ta = 0).
    const Mat3 U_p = J.Rd * Z_pa.transpose(), U_v = J.Rd * Z_va.transpose();
    propagate(comb_xi_, J);
    comb_xi_.tt -= plusTranspose(J.Jd * Z_tg.transpose());
    comb_xi_.tp -= J.Jd * Z_pg.transpose();
    comb_xi_.tv -= J.Jd * Z_vg.transpose();
    comb_xi_.pp -= hdt * plusTranspose(U_p);
    comb_xi_.pv -= hdt * U_v + U_p.transpose();
    comb_xi_.vv -= plusTranspose(U_v);
    // M Pb M^T has the same form as the white-noise input: add both at once.
    addInputNoise(comb_xi_, JJt, va + pa, vg + pg, integ_var_density_, dt);
    X.t_g = phi_bg_ * (Z_tg - pg * J.Jd);
    X.p_a = phi_ba_ * (Z_pa - (pa * hdt) * J.Rd);
    X.p_g = phi_bg_ * Z_pg;
    X.v_a = phi_ba_ * (Z_va - pa * J.Rd);
    X.v_g = phi_bg_ * Z_vg;
    comb_ba_ = phi_ba_ * phi_ba_ * pa + q_ba_;
    comb_bg_ = phi_bg_ * phi_bg_ * pg + q_bg_;
  }

  // Bias Jacobians: J+ = A J - B (accel), A J - C (gyro). The theta rows of J_ba stay zero.
  J_xi_ba_.middleRows<3>(3) += dt_s * J_xi_ba_.bottomRows<3>() - J.hdt * J.Rd;
  J_xi_ba_.bottomRows<3>() -= J.Rd;
  const Mat3 GJ = J.G * J_xi_bg_.topRows<3>();
  J_xi_bg_.middleRows<3>(3) += dt_s * J_xi_bg_.bottomRows<3>() + J.hdt * GJ;
  J_xi_bg_.bottomRows<3>() += GJ;
  J_xi_bg_.topRows<3>() = J.T * J_xi_bg_.topRows<3>() - J.Jd;

  // Mean.
  const Vec3 a_i = f.R * a;  // specific force in frame i
  theta_ += J.Jd * w;
  // The tangent-space form (Jr^-1 of theta) is singular at |theta| = 2 pi: a
  // window must be cut into shorter intervals long before (the pipeline does).
  if (theta_.norm() > kMaxWindowRotationRad) {
    throw std::domain_error("PreintegratedImu::integrate: rotation within one window exceeds " +
                            std::to_string(kMaxWindowRotationRad) + " rad; use shorter state intervals");
  }
  p_ += dt_s * v_ + (0.5 * dt_s * dt_s) * a_i;
  v_ += dt_s * a_i;
  dt_s_ += dt_s;
  ++num_samples_;
}

Vec9 PreintegratedImu::xi() const {
  Vec9 x;
  x << theta_, p_, v_;
  return x;
}

Mat9 PreintegratedImu::covariance() const {
  if (!hasCovariance()) throw std::logic_error("PreintegratedImu::covariance: not kept in CovarianceMode::kCombined");
  return cov_.full();
}

Mat15 PreintegratedImu::combinedCovariance() const {
  if (!hasCombinedCovariance()) {
    throw std::logic_error("PreintegratedImu::combinedCovariance: not kept in CovarianceMode::kPreintegration");
  }
  Eigen::Matrix<double, 9, 6> X;
  X << Mat3::Zero(), comb_xi_b_.t_g, comb_xi_b_.p_a, comb_xi_b_.p_g, comb_xi_b_.v_a, comb_xi_b_.v_g;
  Mat15 P = Mat15::Zero();
  P.topLeftCorner<9, 9>() = comb_xi_.full();
  P.topRightCorner<9, 6>() = X;
  P.bottomLeftCorner<6, 9>() = X.transpose();
  P.diagonal().segment<3>(9).setConstant(comb_ba_);
  P.diagonal().segment<3>(12).setConstant(comb_bg_);
  return P;
}

PreintegratedImu::Delta PreintegratedImu::biasCorrectedDelta(const ImuBias& b) const {
  const Vec3 dba = b.accel - bias_hat_.accel;
  const Vec3 dbg = b.gyro - bias_hat_.gyro;
  Delta d;
  d.theta_rad = theta_ + J_xi_bg_.topRows<3>() * dbg;
  d.R = so3::exp(d.theta_rad);
  d.p_m = p_ + J_xi_ba_.middleRows<3>(3) * dba + J_xi_bg_.middleRows<3>(3) * dbg;
  d.v_m_s = v_ + J_xi_ba_.bottomRows<3>() * dba + J_xi_bg_.bottomRows<3>() * dbg;
  return d;
}

PreintegratedImu::NavState PreintegratedImu::predict(const Pose3& T_w_i, const Vec3& v_w_i, const ImuBias& b_i) const {
  const Delta d = biasCorrectedDelta(b_i);
  const Vec3 g_w = params_.gravityWorld();
  NavState s;
  s.T_w_b.R = T_w_i.R * d.R;
  s.T_w_b.p = T_w_i.p + v_w_i * dt_s_ + 0.5 * dt_s_ * dt_s_ * g_w + T_w_i.R * d.p_m;
  s.v_w = v_w_i + dt_s_ * g_w + T_w_i.R * d.v_m_s;
  return s;
}

}  // namespace rilo
