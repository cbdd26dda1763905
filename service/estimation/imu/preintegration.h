#pragma once
// IMU preintegration between two states i and j (Forster et al., TRO 2017),
// in the tangent-space form (GTSAM's TangentPreintegration): the preintegrated
// measurement is xi = [theta; p; v] in frame i, with deltaR = Exp(theta).
//
// Per sample (Euler: the sample at t_k is held constant over [t_k, t_k + dt]),
// with a = accel - b_a_hat, w = gyro - b_g_hat, R = Exp(theta):
//   theta+ = theta + Jr^-1(theta) w dt
//   p+     = p + v dt + 1/2 R a dt^2
//   v+     = v + R a dt
// The global error of this scheme is O(dt) (first order); it acts like a
// half-sample time shift. On the simulator's LissajousWalk at 800 Hz it is
// ~1e-4 rad and ~5e-4 m/s per second of window (tests/core/preintegration_test).
//
// Linearized error propagation d xi+ = A d xi + B d a + C d w:
//   A = [ I + dt d(Jr^-1 w)/dtheta   0   0   ]      B = [ 0         ]   C = [ Jr^-1 dt ]
//       [ -R [a]x Jr dt^2/2          I   dtI ]          [ R dt^2/2  ]       [ 0        ]
//       [ -R [a]x Jr dt              0   I   ]          [ R dt      ]       [ 0        ]
// - bias Jacobians (first-order correction): J_ba+ = A J_ba - B, J_bg+ = A J_bg - C;
// - 9x9 covariance of xi (order [theta, p, v]) from the white noise only:
//   S+ = A S A^T + B (sa^2/dt) B^T + C (sg^2/dt) C^T + diag(0, si^2 dt I, 0),
//   sa, sg, si the accel, gyro and integration noise densities;
// - 15x15 combined covariance (as in GTSAM's PreintegratedCombinedMeasurements,
//   but with rilo's first-order Gauss-Markov bias): the error state is
//   e = [xi_true - xi_meas; n], n the bias deviation from b_i that the bias
//   process accumulates inside the window (n_0 = 0). With M = [B C]:
//     e+ = F e + noise,  F = [ A  -M  ]       n+ = Phi n + w,  Phi = diag(exp(-dt/tau))
//                            [ 0  Phi ]
//   so P+ = F P F^T + blockdiag(white noise above, Qb(dt)), Qb from
//   ImuParams::biasDiscreteVariance. The bias block stays diagonal; its final
//   value is the covariance of b_j - Phi b_i. The sign convention (xi_true -
//   xi_meas, b_j - Phi b_i) is the residual's, so the matrix is used as is by
//   CombinedImuFactor. Inside the window the deltas use the constant b_i;
//   the mean decay (Phi - I) b_i of a Gauss-Markov bias (size dt/tau) is
//   neglected there and appears only in the bias residual.
//
// Bias correction to b: xi(b) ~= xi + J_ba (b_a - b_a_hat) + J_bg (b_g - b_g_hat)
// (first order, additive in the theta chart).
//
// Cost: the 9x9 and the 15x15 propagations are each most of a sample's
// work, and a factor uses one of them; CovarianceMode picks which are kept
// (the deltas and bias Jacobians always are).
//
// Limits: theta must stay below 2 pi (Jr^-1 is singular there), i.e. well
// under one full turn between two states. integrate() never allocates.
#include "estimation/imu/imu_params.h"
#include "math/imu_bias.h"
#include "math/pose3.h"

namespace rilo {

/// Largest rotation one preintegration window may accumulate (rad): well below
/// the 2 pi singularity of the tangent-space form.
constexpr double kMaxWindowRotationRad = 0.9 * 2.0 * 3.14159265358979323846;

class PreintegratedImu {
 public:
  /// Relative motion from i to j in frame i: deltaR = R_i^T R_j,
  /// p = R_i^T (p_j - p_i - v_i dt - 1/2 g dt^2), v = R_i^T (v_j - v_i - g dt).
  struct Delta {
    Vec3 theta_rad;  ///< Log(deltaR) in the tangent chart of the preintegration (rad)
    Mat3 R;          ///< deltaR = Exp(theta)
    Vec3 p_m;        ///< position delta (m), frame i
    Vec3 v_m_s;      ///< velocity delta (m/s), frame i
  };
  /// Navigation state predicted at j.
  struct NavState {
    Pose3 T_w_b;  ///< pose world-from-body
    Vec3 v_w;     ///< velocity in world (m/s)
  };

  /// Which covariances integrate() propagates.
  enum class CovarianceMode {
    kPreintegration,  ///< 9x9 only: for ImuFactor (+ BiasGaussMarkovFactor)
    kCombined,        ///< 15x15 only: for CombinedImuFactor
    kBoth,            ///< both (tests; a graph that may use either factor)
  };

  /// Validates params (std::invalid_argument naming the field).
  explicit PreintegratedImu(const ImuParams& params, const ImuBias& bias_hat = ImuBias(),
                            CovarianceMode mode = CovarianceMode::kBoth);

  /// Clears the preintegration; bias_hat is the bias the samples are corrected with.
  void reset(const ImuBias& bias_hat);
  /// Adds one sample held over dt_s. Throws std::invalid_argument if dt_s is
  /// not finite and > 0 or a sample is not finite.
  /// Throws std::invalid_argument for non-finite input or dt_s <= 0, and
  /// std::domain_error once the window's rotation exceeds kMaxWindowRotationRad.
  void integrate(const Vec3& accel_m_s2, const Vec3& gyro_rad_s, double dt_s);

  const ImuParams& params() const { return params_; }
  CovarianceMode covarianceMode() const { return mode_; }
  bool hasCovariance() const { return mode_ != CovarianceMode::kCombined; }
  bool hasCombinedCovariance() const { return mode_ != CovarianceMode::kPreintegration; }
  const ImuBias& biasHat() const { return bias_hat_; }
  double dt() const { return dt_s_; }            ///< integrated time (s)
  int numSamples() const { return num_samples_; }

  const Vec3& theta() const { return theta_; }   ///< rad
  Mat3 deltaR() const { return so3::exp(theta_); }
  const Vec3& deltaP() const { return p_; }      ///< m
  const Vec3& deltaV() const { return v_; }      ///< m/s
  Vec9 xi() const;                               ///< [theta; p; v]

  /// d xi / d b_a and d xi / d b_g (9x3, rows [theta, p, v]); the theta rows of J_xi_ba are zero.
  const Mat93& J_xi_ba() const { return J_xi_ba_; }
  const Mat93& J_xi_bg() const { return J_xi_bg_; }
  Mat3 J_theta_bg() const { return J_xi_bg_.topRows<3>(); }     ///< rad / (rad/s)
  Mat3 J_p_ba() const { return J_xi_ba_.middleRows<3>(3); }     ///< m / (m/s^2)
  Mat3 J_p_bg() const { return J_xi_bg_.middleRows<3>(3); }     ///< m / (rad/s)
  Mat3 J_v_ba() const { return J_xi_ba_.bottomRows<3>(); }      ///< (m/s) / (m/s^2)
  Mat3 J_v_bg() const { return J_xi_bg_.bottomRows<3>(); }      ///< (m/s) / (rad/s)

  /// 9x9 covariance of xi, order [theta, p, v], white measurement noise only.
  /// Throws std::logic_error if the mode does not keep it.
  Mat9 covariance() const;
  /// 15x15 covariance of [xi_true - xi_meas; b_j - Phi b_i], order
  /// [theta, p, v, b_a, b_g] (see the header comment). Throws
  /// std::logic_error if the mode does not keep it.
  Mat15 combinedCovariance() const;

  /// Deltas corrected to first order for the bias b (instead of biasHat()).
  Delta biasCorrectedDelta(const ImuBias& b) const;
  /// State at j from the state at i, with world gravity (0, 0, -g) and the bias b_i.
  NavState predict(const Pose3& T_w_i, const Vec3& v_w_i, const ImuBias& b_i) const;

 private:
  /// Symmetric 9x9 [theta, p, v] stored as its upper 3x3 blocks.
  struct SymBlocks {
    Mat3 tt, tp, tv, pp, pv, vv;
    void setZero();
    Mat9 full() const;
  };
  /// Cross-covariance xi-bias (9x6) by 3x3 blocks; the theta/b_a block is always zero.
  struct CrossBlocks {
    Mat3 t_g, p_a, p_g, v_a, v_g;
    void setZero();
  };

  ImuParams params_;
  ImuBias bias_hat_;
  CovarianceMode mode_;
  double accel_var_density_;  ///< sa^2, (m/s^2)^2/Hz
  double gyro_var_density_;   ///< sg^2, (rad/s)^2/Hz
  double integ_var_density_;  ///< si^2, (m/s)^2/Hz

  double dt_s_ = 0.0;
  int num_samples_ = 0;
  Vec3 theta_, p_, v_;
  Mat93 J_xi_ba_, J_xi_bg_;
  SymBlocks cov_;                  ///< white noise only
  SymBlocks comb_xi_;              ///< combined: xi block
  CrossBlocks comb_xi_b_;          ///< combined: xi-bias block
  double comb_ba_ = 0.0, comb_bg_ = 0.0;  ///< combined: bias block, per axis (isotropic, diagonal)

  // Bias transition and added variance for the last dt (IMU dt rarely changes).
  double bias_dt_cached_ = -1.0;
  double phi_ba_ = 1.0, phi_bg_ = 1.0, q_ba_ = 0.0, q_bg_ = 0.0;
};

}  // namespace rilo
