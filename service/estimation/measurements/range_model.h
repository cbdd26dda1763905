#pragma once
// How a two-way range enters an estimator (graph stream, batch, EKF): with
// the configured robust loss, or, when the receiver flags it as NLOS
// (RangeNoiseParams::nlos_power_gap_db, the DW1000/DW3000 RX-level-minus-
// first-path-power indicator) and the model is "asymmetric", with the
// model's NLOS component alone (default, flagged_nlos_component): the range
// shifted by the expected excess and its sigma widened to the component's
// curvature (nlos_component_loss.h); or with the mixture at the larger
// prior NLOS weight flagged_nlos_weight, the range shifted by the site's
// excess when one was set. Ranges without the powers (NaN) keep the
// configured mixture.
//
// The component's shift: the excess of the range's power-gap bin where the
// calibration has one (setGapExcess), else the site's flagged excess once setFlaggedExcess was
// called (the Localizer's on-line estimate, range_consistency.h, which it
// sets to 0 before the first update), else the component's own mode. The
// fixed mode assumes the excess: where walls attenuate the first path
// without delaying it (rilo sim --nlos-severity 0) it shortened every flagged
// range for nothing and the error tripled, while the estimated shift cost
// little there (measured: docs/noise-models.md, Figures behind the defaults).
// A flag that stands in from the RX level (Measurement::gap_from_rx_level,
// Localizer::withRxLevelIndicator) never takes the site's excess, which is
// learnt from the receiver's own flags: its bin's excess, else the mode (the
// mixture: no shift). Measured: docs/noise-models.md, session 31. A range
// flagged only by its anchor's memory (Measurement::nlos_from_memory,
// nlos_memory.h) takes the mode too: its gap's bin is one of the LOS ones.
#include <string>

#include "estimation/measurements/los_gap_calibration.h"
#include "estimation/measurements/measurement.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {

/// One range as the factor or the EKF update takes it.
struct RangeTerm {
  double range_m;      ///< measured range, less the expected NLOS excess when flagged (m)
  double sigma_m;      ///< std-dev the residual is whitened with (m)
  RobustLossPtr loss;  ///< never null
  bool flagged_nlos;   ///< the receiver's indicator said NLOS and the NLOS component is used
};

class RangeModel {
 public:
  /// loss_name: a makeRangeLoss name. Throws std::invalid_argument for a bad
  /// name or parameter (naming it), and for a NaN nlos_power_gap_db.
  RangeModel(const std::string& loss_name, const RangeNoiseParams& noise);

  /// Whether m (a two-way range) is flagged as NLOS and gets the NLOS component.
  bool flagsNlos(const Measurement& m) const {
    return flagged_loss_ != nullptr && m.kind == Measurement::Kind::kRange &&
           (m.power_gap_db > gap_db_ || m.nlos_from_memory);
  }
  /// m as a range term at the LOS std-dev sigma_m (MeasurementNoise::sigma).
  RangeTerm term(const Measurement& m, double sigma_m) const;
  /// The configured loss (the mixture for "asymmetric").
  const RobustLossPtr& loss() const { return loss_; }
  /// Whether the indicator is in use (asymmetric model, finite threshold).
  bool usesIndicator() const { return flagged_loss_ != nullptr; }
  /// The site's excess of a flagged range (m), taken off it before its loss
  /// (the component's mode no longer applies once this was called).
  void setFlaggedExcess(double excess_m) {
    flagged_excess_m_ = excess_m;
    excess_set_ = true;
  }
  double flaggedExcess() const { return flagged_excess_m_; }
  /// The site's flag threshold (dB; the Localizer's calibration,
  /// los_gap_calibration.h), in place of nlos_power_gap_db. No effect while
  /// the indicator is off.
  void setNlosGapDb(double gap_db) { gap_db_ = gap_db; }
  double nlosGapDb() const { return gap_db_; }
  /// The excess per power-gap bin (the Localizer's calibration,
  /// los_gap_calibration.h): a flagged range in a bin that has one takes it
  /// as its shift in place of the site's flagged excess.
  void setGapExcess(const GapExcessTable& table) { gap_excess_ = table; }
  const GapExcessTable& gapExcess() const { return gap_excess_; }

 private:
  RobustLossPtr loss_;
  RobustLossPtr flagged_loss_;                          ///< null: indicator off
  std::shared_ptr<const NlosComponentLoss> component_;  ///< set when flagged ranges get the NLOS component
  double gap_db_;
  double flagged_excess_m_ = 0.0;
  GapExcessTable gap_excess_;  ///< all NaN until set
  bool excess_set_ = false;  ///< setFlaggedExcess was called: its value replaces the component's mode
};

}  // namespace rilo
