#pragma once
// Between-factor of the IMU bias process (Ranging-IMU Fusion paper, Sec. III-A): each of the
// six bias axes follows a first-order Gauss-Markov process
//   db/dt = -b / tau + w,  w white with driving density q   (see ImuParams),
// so over dt
//   b_j = Phi b_i + n,  Phi = exp(-dt/tau),  Var(n) = q^2 tau/2 (1 - exp(-2 dt/tau))
// exactly; for tau = +inf (random walk) Phi = 1 and Var(n) = q^2 dt.
// Residual (6, order [accel xyz, gyro xyz]): r = (b_j - Phi b_i) / sigma_n per axis.
// Jacobians: d r/d b_i = -diag(Phi / sigma_n), d r/d b_j = diag(1 / sigma_n).
#include "estimation/graph/factor.h"
#include "estimation/imu/imu_params.h"

namespace rilo {

class BiasGaussMarkovFactor final : public Factor {
 public:
  /// Keys {bias_i, bias_j} (ImuBias), dt_s = t_j - t_i (s). Throws
  /// std::invalid_argument on dt_s not finite and > 0, or invalid params.
  BiasGaussMarkovFactor(Key bias_i, Key bias_j, double dt_s, const ImuParams& params);

  int dim() const override { return 6; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  double dt() const { return dt_s_; }                     ///< s
  const Vec6& transition() const { return phi_; }         ///< diag(Phi)
  const Vec6& sigma() const { return sigma_; }            ///< std-dev of n per axis (m/s^2, rad/s)

 private:
  double dt_s_;
  Vec6 phi_;
  Vec6 sigma_;
  Vec6 inv_sigma_;
};

}  // namespace rilo
