#pragma once
// How a TDoA range difference enters an estimator (graph stream, EKF), using
// the tag's receive diagnostics of its two packets when the row has them
// (tdoa.csv rssi/fp columns; the DW1000/DW3000 RX-level-minus-first-path-
// power indicator, as for two-way ranges, range_model.h). The IMU-Ultrasonic-UWB paper weights
// its TDoA "based on real-time channel conditions"; this is that, per packet:
//  - neither packet flagged (gap <= range_noise.nlos_power_gap_db), or no
//    diagnostics: the configured TDoA loss at the TDoA sigma (with both
//    packets' diagnostics, the configured sigma even under dynamic
//    covariance: vouchedLos);
//  - one packet flagged: its path is the late one, so the difference has a
//    one-sided error: positive when b's packet is flagged, negative when a's.
//    The row is oriented so that the flagged path is b's (anchors swapped,
//    difference negated, TdoaTerm::reversed) and gets tdoa_flagged_loss, an
//    NLOS-tail loss whose long side is r > 0 (tdoa_factor.h's sign), at the
//    receiver's flagged NLOS weight (flagged_nlos_weight, 0.45);
//  - both flagged: the two excesses partly cancel and the sign is unknown: the
//    configured loss at tdoa_both_flagged_sigma_factor times the sigma;
//  - either packet's gap above max_power_gap_db (deep NLOS: several walls,
//    metres of excess): the row is not used at all (gated(); the Localizer
//    drops it on arrival and counts it).
#include <cmath>
#include <string>

#include "estimation/measurements/measurement.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {

/// One TDoA row as the factor or the EKF update takes it:
/// value_m = |p - A_b| - |p - A_a| with (a, b) = (anchor_a, anchor_b).
struct TdoaTerm {
  std::uint32_t anchor_a = 0;  ///< the reference, after orientation
  std::uint32_t anchor_b = 0;
  double value_m = 0.0;        ///< range difference (m), negated when reversed
  double sigma_m = 0.0;        ///< std-dev the residual is whitened with (m)
  RobustLossPtr loss;          ///< never null
  int flagged_packets = 0;     ///< 0, 1 or 2
  bool reversed = false;       ///< the measurement's a and b were swapped (a's packet was flagged)
};

struct TdoaModelParams {
  std::string loss = "huber";             ///< unflagged rows (makeRangeLoss name)
  std::string flagged_loss = "asymmetric";  ///< one packet flagged, oriented (makeRangeLoss name)
  double sigma_m = 0.15;                  ///< LOS std-dev of a difference (m)
  double both_flagged_sigma_factor = 3.0; ///< both flagged: sigma times this (>= 1)
  double one_flagged_sigma_factor = 2.0;  ///< symmetricSigma of a row with one packet flagged (>= 1)
  bool use_indicator = true;              ///< false: every row as unflagged
  /// Rows with a packet whose gap exceeds this are gated (dB; +inf: none).
  /// A packet's gap grows with the walls and the excess on its path, so the
  /// rows with the largest gaps carry the largest errors. Measured:
  /// docs/noise-models.md, "Gating deep-NLOS TDoA packets (session 26)" and
  /// Figures behind the defaults.
  double max_power_gap_db = 15.0;
};

class TdoaModel {
 public:
  /// noise: the receiver's range noise (its nlos_power_gap_db is the threshold;
  /// its sigma is replaced by params.sigma_m). Throws std::invalid_argument
  /// for a bad loss name or parameter, naming it.
  TdoaModel(const TdoaModelParams& params, const RangeNoiseParams& noise);

  /// Packets of m flagged as NLOS (0, 1, 2); 0 without diagnostics.
  int flaggedPackets(const Measurement& m) const;
  /// Whether m is a TDoA row the receiver vouches for: both packets'
  /// diagnostics reported, neither flagged. Such a row keeps the configured
  /// LOS sigma even when dynamic covariance is on (the estimators ask this
  /// before MeasurementNoise::sigma): its pair's residual statistics are
  /// mostly those of the pair's NLOS rows, and widened the LOS rows with them
  /// (measured: docs/noise-models.md, "TDoA rows the receiver flags (session 15)").
  bool vouchedLos(const Measurement& m) const {
    return use_indicator_ && m.kind == Measurement::Kind::kTdoa && !std::isnan(m.power_gap_db) &&
           !std::isnan(m.power_gap_b_db) && !flagged(m.power_gap_db) && !flagged(m.power_gap_b_db);
  }
  /// m (a TDoA measurement) as a term at the row's std-dev sigma_m
  /// (MeasurementNoise::sigma; params.sigma_m unless dynamic covariance is on).
  TdoaTerm term(const Measurement& m, double sigma_m) const;
  /// The std-dev of m for an estimator that keeps the configured symmetric
  /// loss and the measurement's orientation (the EKF, whose group update
  /// correlates rows by their reference): sigma_m, times
  /// one_flagged_sigma_factor or both_flagged_sigma_factor when flagged.
  double symmetricSigma(const Measurement& m, double sigma_m) const;
  /// Whether m (a TDoA row) has a packet whose gap exceeds
  /// max_power_gap_db: too deep in NLOS to use. False without the indicator,
  /// for unreported gaps (NaN) and for other kinds.
  bool gated(const Measurement& m) const {
    return use_indicator_ && m.kind == Measurement::Kind::kTdoa &&
           (m.power_gap_db > max_gap_db_ || m.power_gap_b_db > max_gap_db_);
  }
  /// The configured loss of unflagged rows.
  const RobustLossPtr& loss() const { return loss_; }

 private:
  bool flagged(double gap_db) const { return use_indicator_ && gap_db > gap_db_; }  // NaN: not flagged

  RobustLossPtr loss_, flagged_loss_;
  double gap_db_;
  double both_factor_, one_factor_;
  bool use_indicator_;
  double max_gap_db_;
};

}  // namespace rilo
