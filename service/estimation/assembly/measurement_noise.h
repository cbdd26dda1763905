#pragma once
// The sigma each new measurement factor (graph stream) or filter update (EKF
// estimator) gets: the configured one of its kind (RangeImuGraphParams:
// range_noise.sigma_m, tdoa_sigma_m, ultrasonic_sigma_m), or, with dynamic
// covariance on, DynamicCovariance's per-link estimate (the IMU-Ultrasonic-UWB paper's "dynamic
// covariance estimation ... adjusts measurement weights based on real-time
// channel conditions"). Links: a UWB anchor for ranges, an unordered anchor
// pair for TDoA, a beacon for ultrasonic ranges (NoiseKey).
//
// What the estimate is fed, and why (DynamicCovariance needs residuals whose
// spread is the measurement's own, not the state's):
// - EKF (noteInnovation): the innovation y = z - h(x_prior) and its predicted
//   variance H P H^T, both exact for the filter (DynamicCovariance subtracts
//   the latter).
// - Graph stream (notePrediction, then notePostFit once the smoother has
//   absorbed the state): neither the innovation alone (its spread includes
//   the prediction error, the state's marginal is not at hand: 2 cm ultrasonic
//   ranges would look like 4 cm ones) nor the post-fit residual alone (the
//   newest state was fitted to its own measurements: an ultrasonic range
//   outweighing the IMU prediction keeps a third of its spread) measures the
//   link. Their product does: for a linear-Gaussian update, e_post =
//   R S^-1 e_innov, so E[e_innov e_post^T] = R (Desroziers et al. 2005,
//   "Diagnosis of observation, background and analysis-error statistics in
//   observation space"); for one measurement e_innov e_post = (R/S) e_innov^2
//   >= 0 and r = sign(e_innov) sqrt(e_innov e_post) is N(0, R) exactly, so the
//   robust warm-up and clipping of DynamicCovariance apply unchanged. Fed:
//   r = sign(e_innov) sqrt(max(0, e_innov e_post)), predicted variance 0. A
//   measurement the robust loss ignored keeps e_post ~ e_innov: it arrives as
//   a large residual and is clipped (an NLOS burst barely moves the link). The
//   residuals use the surveyed anchors; the innovation is taken at the IMU
//   prediction the stream gives as initial value, the post-fit residual at
//   the smoother's estimate of the same state right after its update
//   (filtered, not smoothed: available one state later, not a lag later).
//   Measurements that reach a state late (carried ranges) are not fed.
//
// Measured on the hall and office TDoA + ultrasonic sims (docs/noise-models.md,
// Figures behind the defaults): it lowers the sliding window's and D-iSAM2's
// error; two-way ranges (asymmetric loss) got worse, hence
// DynamicCovarianceOptions::range off; the EKF stays erratic with or without
// it. The library default is off (RangeImuStreamOptions, EkfParams); `rilo
// replay` turns it on for the graph estimators when TDoA rows are used.
//
// The same post-fit residuals of TDoA rows feed TdoaGapExcess
// (graph.tdoa_gap_excess, with the NLOS indicator on), the per gap bin NLOS
// excess the stream takes off each row (tdoaExcessCorrection), with or
// without dynamic covariance.
//
// Fixed storage: DynamicCovariance's table and a pending buffer of
// max_pending measurements (one state's group; more are not fed, counted in
// pendingOverflow()), all allocated in the constructor; the note* calls and
// sigma() never allocate. Single-threaded.
#include <cstdint>
#include <optional>
#include <vector>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/measurements/measurement.h"
#include "estimation/noise/dynamic_covariance.h"
#include "estimation/noise/tdoa_gap_excess.h"
#include "math/pose3.h"

namespace rilo {

/// DynamicCovarianceParams with the graph's sigmas as nominal levels.
DynamicCovarianceParams dynamicCovarianceParamsFor(const RangeImuGraphParams& graph,
                                                   const DynamicCovarianceParams& params);

class MeasurementNoise {
 public:
  /// `p_w_anchors[id]`: surveyed UWB anchors; ultrasonic beacons and lever
  /// arms from `graph`. Throws std::invalid_argument (DynamicCovarianceParams
  /// fields, max_pending < 1) when enabled; (TdoaGapExcessParams fields,
  /// max_pending < 1) when graph.tdoa_gap_excess is on with the indicator.
  MeasurementNoise(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph,
                   const DynamicCovarianceOptions& options);

  bool dynamic() const { return cov_.has_value(); }
  /// What to take off a TDoA row's measured difference for its packets' NLOS
  /// excess (m; TdoaGapExcess::correction); 0 when the learner is off.
  double tdoaExcessCorrection(const Measurement& m) const {
    return gap_excess_ ? gap_excess_->correction(m.power_gap_db, m.power_gap_b_db) : 0.0;
  }
  /// The learner of the TDoA packets' excess (nullptr when off).
  const TdoaGapExcess* tdoaGapExcess() const { return gap_excess_ ? &*gap_excess_ : nullptr; }
  /// Whether m's kind gets an estimated sigma (dynamic and in the options' kinds).
  bool dynamicKind(Measurement::Kind kind) const {
    return cov_.has_value() && dynamic_kind_[static_cast<std::size_t>(kind)];
  }
  /// The link's current sigma (m); the kind's configured sigma when off or
  /// while the link warms up.
  double sigma(const Measurement& m) const;
  /// The configured sigma of m's kind (m).
  double nominalSigma(Measurement::Kind kind) const;
  static NoiseKey keyOf(const Measurement& m);
  /// h(x) of m at the body pose T_w_b (surveyed anchors; ultrasonic: range only).
  double predict(const Measurement& m, const Pose3& T_w_b) const;

  /// Whether notePrediction keeps m for notePostFit: its kind's sigma is
  /// estimated, or it is a TDoA row and the excess learner is on.
  bool learnsFrom(Measurement::Kind kind) const {
    return dynamicKind(kind) || (kind == Measurement::Kind::kTdoa && gap_excess_.has_value());
  }
  /// Graph stream: m's factor on state `state_index` (at state_t_ns) was
  /// created with T_w_b_predicted and v_w_predicted as the state's initial
  /// values; a measurement after the state (any kind) is predicted where the
  /// velocity takes the tag by its time, as its factor does (RangeTimeOffset). A note
  /// for another state than the pending one drops the pending notes (their
  /// state was never reported back). No-op when off.
  void notePrediction(std::uint64_t state_index, std::int64_t state_t_ns, const Measurement& m,
                      const Pose3& T_w_b_predicted, const Vec3& v_w_predicted);
  /// Graph stream: the smoother's estimate of `state_index` after it absorbed
  /// the state: feeds the pending notes of that state (see the file comment)
  /// and clears them. Notes of another state are kept. No-op when off.
  void notePostFit(std::uint64_t state_index, const Pose3& T_w_b_updated, const Vec3& v_w_updated);
  /// EKF: innovation y = z - h(x_prior) (m) and H P H^T (m^2) of m. No-op when off.
  /// Not fed to the excess learner: the EKF builds its MeasurementNoise
  /// without one (ekf_estimator.cpp).
  void noteInnovation(const Measurement& m, double innovation_m, double predicted_var_m2);

  /// The estimator (nullptr when off).
  const DynamicCovariance* covariance() const { return cov_ ? &*cov_ : nullptr; }
  std::uint64_t residualsFed() const { return fed_; }            ///< residuals DynamicCovariance took (warm-up or update)
  std::uint64_t pendingOverflow() const { return overflow_; }    ///< notes dropped for a full pending buffer
  std::size_t pending() const { return pending_.size(); }

 private:
  struct Pending {
    Measurement m;
    double innovation_m = 0.0;
    std::int64_t state_t_ns = 0;  ///< the time of the state its factor is on
  };
  /// h(x) of p at the state's pose and velocity.
  double predictAt(const Pending& p, const Pose3& T_w_b, const Vec3& v_w) const;

  void count(CovarianceUpdate u);

  std::vector<Vec3> p_w_anchors_;
  std::vector<Vec3> p_w_ultrasonic_;
  Vec3 p_b_tag_, p_b_ultrasonic_;
  std::vector<TagLeverArm> tag_arms_;  ///< RangeImuGraphParams::tag_lever_arms
  double sigma_range_m_, sigma_tdoa_m_, sigma_ultrasonic_m_;
  std::optional<DynamicCovariance> cov_;
  std::optional<TdoaGapExcess> gap_excess_;  ///< graph.tdoa_gap_excess, fed post-fit residuals
  bool dynamic_kind_[3] = {false, false, false};  ///< by Measurement::Kind
  std::vector<Pending> pending_;  ///< reserved to max_pending
  std::size_t max_pending_ = 0;
  std::uint64_t pending_index_ = 0;
  std::uint64_t fed_ = 0, overflow_ = 0;
};

}  // namespace rilo
