#pragma once
// Error-state EKF for UWB ranging (TWR), TDoA and ultrasonic ranges with IMU
// propagation: the filtering baseline rilo's smoother is compared against
// (the IMU-Ultrasonic-UWB paper's "EKF" column) and a cheap fallback estimator.
//
// State and chart: ekf_state.h (nominal R_w_b, p_w_b, v_w, b_a, b_g; 15-dim
// error [dtheta body/right, dp world, dv world, dba, dbg]).
//
// Propagation (propagate(ImuSample)): midpoint integration between the
// previous and the current sample (ekf_propagation.h), P <- F P F^T + Q with
// Q from the ImuParams densities for a sample held over dt (sg, sa, si the
// gyro, accel and integration densities):
//   Q_theta = sg^2 dt I,  Q_v = sa^2 dt I,  Q_pv = sa^2 dt^2/2 I,
//   Q_p = (sa^2 dt^3/4 + si^2 dt) I,  Q_bias = ImuParams::biasDiscreteVariance(dt)
// and, for an interval longer than ImuParams::gap_threshold_s (dropped
// samples), the gap's unmeasured motion as a constant input error of std-dev
// ga (accel) and gg (gyro) over dt, as preintegration adds it:
//   Q_theta += gg^2 dt^2 I,  Q_v += ga^2 dt^2 I,  Q_pv += ga^2 dt^3/2 I,  Q_p += ga^2 dt^4/4 I
// and the nominal bias decaying with the Gauss-Markov transition. With
// EkfParams::velocity_noise_density q > 0, an unmodelled white acceleration:
//   Q_v += q^2 dt I,  Q_pv += q^2 dt^2/2 I,  Q_p += q^2 dt^3/3 I. The first
// sample after initialize() at the filter's time only opens the interval; a
// first sample after it is held over [t_state, t_sample] (Euler).
//
// Updates (updateRange / updateTdoa / updateUltrasonic), all at the filter's
// current time (propagate to the measurement first; the caller interleaves
// the streams in time order):
//   1. y = z - h(x), S = H P H^T + R, R = diag(sigma^2).
//   2. Chi-square gate: y^T S^-1 y > gate (EkfParams, by row count) ->
//      rejected (kGated) and counted; the state is untouched.
//   3. Robust re-weighting (with a loss, range row only): the variance of the
//      range row becomes sigma^2 / w, w = loss->weight(r), r the WHITENED
//      residual (z - h)/sigma like the smoother's factors see it: first at the
//      predicted state (r = y/sigma, the smoother's first linearization),
//      then (EkfParams::robust_iterations - 1 times, default once more) at the
//      residual of the updated state that weight implies, R_w S_w^-1 y (exact
//      for the linearized model, no state copy). This is IRLS on the MAP of
//      prior + robust likelihood, so the signed asymmetric NLOS loss behaves
//      as in the smoother: r > 0 (measured longer) is down-weighted, r <= its
//      decision point is plain Gaussian. w below min_robust_weight -> kZeroWeight.
//   4. K = P H^T S_w^-1; Joseph form P = (I - K H) P (I - K H)^T + K R_w K^T,
//      evaluated as two rank-M corrections (O(15^2 M), exactly Joseph's
//      expression), then symmetrized.
//   5. Injection x <- x (+) K y and error reset: the new error is
//      dtheta' = Jr(dtheta_hat) (dtheta - dtheta_hat), so the theta rows and
//      columns of P are mapped by G = Jr(dtheta_hat) = I - hat(dtheta_hat)/2 +
//      O(|dtheta_hat|^2) (exact first-order reset of the right chart; the
//      other blocks are additive and need no reset).
// Ultrasonic with an elevation row is a 2-row update (2-dof gate); the loss
// weights only the range row (the elevation row is a Gaussian height
// expectation), so unlike UltrasonicFactor an asymmetric loss is allowed.
//
// Hot path: propagate() and the updates use fixed-size Eigen only and never
// allocate (tests/core/ekf_alloc_test.cpp counts operator new); only the error
// paths (exceptions) allocate. Single-threaded.
//
// Known limits: the gate trusts the prior S, so a filter that has diverged
// (or been started far off with a small covariance) gates good measurements
// too: watch counters() for a run of gated updates and re-initialize. For
// TDoA groups, gate recovery (updateTdoaGroup) lets such rows back in once the
// refused share stays high, and EkfParams::velocity_noise_density keeps the
// velocity from being trusted beyond what persistent NLOS errors allow
// (issue 7: office sims ran away with both off). In simulation
// (tests/core/ekf_tracking_test.cpp) the mean NEES is a little above its
// dof, the theta and gyro-bias blocks slightly overconfident: the usual EKF
// linearization optimism, no stabilising noise is added. On the office TDoA
// sims (NLOS excess persistent over seconds, treated as white) the position
// sigma stays several times below the error; and a start whose velocity is
// metres per second off with a tight covariance (where D-iSAM2 runs away too
// and the sliding window does not) slides along a TDoA hyperbola the few
// audible anchors cannot pin, with small innovations, until the Localizer's
// rejection share re-initializes it. Figures: docs/noise-models.md, Figures
// behind the defaults.
//
// TDoA groups (updateTdoaGroup) exist because, on the office sims, one-by-one
// scalar updates of a group's rows with a 1-dof gate each were both more
// erratic (measured: docs/noise-models.md, Figures behind the defaults) and
// wrong in principle: rows of one TDMA round share anchors, so their errors
// are correlated.
#include <cstdint>
#include <optional>

#include "estimation/ekf/ekf_measurement_models.h"
#include "estimation/ekf/ekf_params.h"
#include "estimation/ekf/ekf_results.h"
#include "estimation/ekf/ekf_state.h"
#include "estimation/factors/ultrasonic_factor.h"
#include "estimation/imu/state_estimate.h"
#include "estimation/noise/robust_loss.h"
#include "sensors/samples.h"

namespace rilo {

/// One TDoA row of a group update: diff_m = |tag - B| - |tag - A| (m) with
/// std-dev sigma_m; the anchor ids say which rows share a path (correlation).
struct EkfTdoaRow {
  Vec3 p_w_anchor_a = Vec3::Zero();
  Vec3 p_w_anchor_b = Vec3::Zero();
  std::uint32_t anchor_a = 0;
  std::uint32_t anchor_b = 0;
  double diff_m = 0.0;
  double sigma_m = 0.0;
};

/// Fixed-capacity (kEkfMaxGroupRows) dynamic sizes of a group update: no heap.
using EkfGroupVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kEkfMaxGroupRows, 1>;
using EkfGroupMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kEkfMaxGroupRows, kEkfMaxGroupRows>;

/// Measurement covariance of n TDoA rows (n <= kEkfMaxGroupRows):
///   R_ij = sigma_i sigma_j (share C_ij + (1 - share) delta_ij),
///   C_ij = 1/2 sum_c D_ic D_jc,  D_ic = +1 if c is row i's anchor b, -1 if its anchor a,
/// i.e. each row's error is e_b - e_a + noise with the path errors e_c of
/// variance share sigma^2 / 2 each (C_ii = 1): rows with a common anchor
/// correlate by +-share/2, a chain a->b, b->c by -share/2. Positive definite
/// for share < 1. Throws std::invalid_argument for n out of range.
EkfGroupMat tdoaGroupCovariance(const EkfTdoaRow* rows, int n, double share);
/// 99.9 % quantile of the chi-square distribution with dof degrees of freedom, 1 <= dof <= kEkfMaxGroupRows.
double chiSquare999(int dof);

class ErrorStateEkf {
 public:
  /// Validates params (std::invalid_argument naming the field).
  explicit ErrorStateEkf(const EkfParams& params = EkfParams());

  /// Starts (or restarts) the filter at t_ns with the nominal state and the
  /// 15x15 error covariance (order of ekf_state.h). Counters are kept.
  /// Throws std::invalid_argument ("state", "covariance") for a non-finite
  /// state or a covariance that is not finite, symmetric and positive definite.
  void initialize(std::int64_t t_ns, const EkfState& state, const Mat15& covariance);
  /// Same from the pipeline's StateEstimate (its index is echoed by estimate()).
  void initialize(const StateEstimate& estimate, const Mat15& covariance);

  /// Propagates to sample.t_ns. Throws std::logic_error before initialize(),
  /// std::invalid_argument for a non-finite gyro/accel sample. dt <= 0 and
  /// gaps > max_imu_dt_s are reported (and counted), not thrown: the filter
  /// does not move. After a gap it keeps refusing until initialize() resumes it.
  PropagateStatus propagate(const ImuSample& sample);

  /// Two-way range z = range_m to the anchor p_w_anchor from the antenna at
  /// lever arm p_b_tag, standard deviation sigma_m. loss: optional robust
  /// loss on the whitened signed residual (not owned; nullptr = Gaussian).
  /// Throws std::invalid_argument naming a non-finite argument or sigma_m <= 0,
  /// std::logic_error before initialize().
  EkfUpdateResult updateRange(const Vec3& p_w_anchor, const Vec3& p_b_tag, double range_m, double sigma_m,
                              const RobustLoss* loss = nullptr);
  /// TDoA range difference z = diff_m = |tag - B| - |tag - A| (m). Also throws
  /// when the two anchors coincide.
  EkfUpdateResult updateTdoa(const Vec3& p_w_anchor_a, const Vec3& p_w_anchor_b, const Vec3& p_b_tag, double diff_m,
                             double sigma_m, const RobustLoss* loss = nullptr);
  /// Ultrasonic range from the receiver at p_b_us, optionally with the
  /// elevation row of UltrasonicFactor (delta_h_m, sigma_h_m > 0).
  EkfUpdateResult updateUltrasonic(const Vec3& p_w_anchor, const Vec3& p_b_us, double range_m, double sigma_m,
                                   const std::optional<UltrasonicElevation>& elevation = std::nullopt,
                                   const RobustLoss* loss = nullptr);

  /// The n TDoA rows of one update group (n <= kEkfMaxGroupRows) as one
  /// update, all at the filter's time (tag antenna at p_b_tag):
  ///   1. Prior innovations y, S = H P H^T + R, R = tdoaGroupCovariance(share).
  ///   2. Gate: while y^T S^-1 y > chiSquare999(m) gate_group_scale over the m
  ///      remaining rows, the row of the largest |y_i| / sqrt(S_ii) is gated.
  ///   3. Iterated update (EkfParams::group_iterations): at the iterate
  ///      x_j = x (+) d_j, rows re-weighted by the loss at their whitened
  ///      residual (z - h(x_j)) / sigma (R_w = W^-1/2 R W^-1/2; a weight below
  ///      min_robust_weight drops the row from that iteration), relinearized
  ///      there, and d_{j+1} = K_j (z - h(x_j) + H_j d_j) (Gauss-Newton on the
  ///      fixed prior and the re-weighted likelihood: the iterated EKF).
  ///   4. Joseph covariance with the last K, H, R_w; injection of d and reset.
  /// Gate recovery (EkfParams::recovery_gated_share): while the average share
  /// of refused rows of the earlier groups (gatedShare()) is above the
  /// threshold, the rows step 2 refuses are kept for step 3 all the same
  /// (EkfGroupResult::recovered, counters().tdoa_recovered), and the group
  /// enters the average as refusing none.
  /// Rows are counted in counters().tdoa. Throws std::invalid_argument for a
  /// bad n, non-finite rows, sigma <= 0 or equal anchors in a row.
  EkfGroupResult updateTdoaGroup(const EkfTdoaRow* rows, int n, const Vec3& p_b_tag, const RobustLoss* loss = nullptr);

  /// Soft height band on the body origin (HeightBandFactor's model): when
  /// p_w_b.z is outside [z_min_m, z_max_m], an update towards the nearer bound
  /// with std-dev sigma_m; inside, nothing. Never gated (it is a prior, not a
  /// measurement that can be an outlier). Returns whether it updated.
  bool applyHeightBand(double z_min_m, double z_max_m, double sigma_m);
  /// Zero-mean prior on the vertical velocity v_w.z with std-dev sigma_m_s
  /// (the graph's PriorVec3Factor of verticalSpeedPriorSigma, once per group
  /// of measurements, which is one graph state): a pseudo-measurement, never gated.
  void applyVerticalSpeedPrior(double sigma_m_s);
  /// Zero-mean prior on the whole velocity v_w with std-dev sigma_m_s per
  /// axis (the graph's standstill PriorVec3Factor,
  /// RangeImuGraphParams::zero_velocity_sigma_m_s): never gated.
  void applyZeroVelocityPrior(double sigma_m_s);

  bool initialized() const { return initialized_; }
  std::int64_t t_ns() const { return t_ns_; }          ///< time of the state (ns)
  const EkfState& state() const { return x_; }
  const Mat15& covariance() const { return P_; }      ///< error covariance, order of ekf_state.h
  /// The state as the pipeline reports it (t_ns, pose, velocity, bias; index
  /// as given to initialize()).
  StateEstimate estimate() const;
  /// 6x6 pose covariance in the smoother's Pose3 chart [phi; rho], rho = R^T dp (body).
  Mat6 poseCovarianceInRetractionChart() const;
  const EkfCounters& counters() const { return counters_; }
  /// Exponential average of the share of TDoA group rows the gate refused
  /// (EkfParams::recovery_window_groups; a recovered group counts as 0); gate
  /// recovery is on while it is above EkfParams::recovery_gated_share. 0 after initialize().
  double gatedShare() const { return gated_share_; }
  void resetCounters() { counters_ = EkfCounters(); }
  const EkfParams& params() const { return params_; }

 private:
  template <int M>
  EkfUpdateResult update(const EkfPrediction<M>& pred, const Eigen::Matrix<double, M, 1>& z,
                         const Eigen::Matrix<double, M, 1>& sigma, const RobustLoss* loss, double gate_chi2,
                         EkfUpdateCounts& counts);
  void requireInitialized(const char* what) const;
  /// White-noise Q of ImuParams over dt, plus the gap input variance when dt > gap_threshold_s.
  void addProcessNoise(double dt_s);
  /// Injects the error estimate dx into the nominal state and resets the
  /// covariance to the new error's chart (rotation block through Jr(dtheta)).
  void injectAndReset(const Vec15& dx);
  /// Scalar zero-mean update of velocity axis `axis` (0..2) with variance r.
  void updateVelocityAxis(int axis, double r);

  EkfParams params_;
  Vec3 g_w_;
  bool initialized_ = false;
  std::int64_t t_ns_ = 0;
  std::uint64_t index_ = 0;  ///< StateEstimate::index given at initialize()
  EkfState x_;
  Mat15 P_ = Mat15::Identity();
  Mat15 F_;  ///< scratch: transition of the last step
  bool has_last_sample_ = false;
  ImuSample last_sample_;
  EkfCounters counters_;
  double gated_share_ = 0.0;  ///< average share of refused TDoA group rows (gate recovery, EkfParams)

  // Bias transition and added variance for the last dt (IMU dt rarely changes).
  double bias_dt_cached_s_ = -1.0;
  Vec6 bias_phi_ = Vec6::Ones();
  Vec6 bias_q_ = Vec6::Zero();
};

}  // namespace rilo
