#pragma once
// Builds the robust loss of range-like factors from a configuration name.
// The losses act on the whitened residual r = (measured - predicted) / sigma_m,
// so every parameter below is given in sigmas except the metric NLOS scale.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "estimation/noise/nlos_component_loss.h"
#include "estimation/noise/robust_loss.h"

namespace rilo {

struct RangeNoiseParams {
  /// IQR of N(0, 1): 2 * 0.6744897501960817. The Ranging-IMU Fusion paper (Sec. III-B)
  /// derives the half-Cauchy scale from the IQR of the Gaussian ranging noise.
  static constexpr double kGaussianIqrPerSigma = 1.3489795003921634;

  double sigma_m = 0.15;      ///< LOS range std-dev [m] (Ranging-IMU Fusion paper: 0.1-0.2 m for UWB first-path noise)
  double huber_k = 1.345;     ///< Huber threshold [sigmas]
  double cauchy_c = 2.3849;   ///< Cauchy scale [sigmas]
  /// Half-Cauchy scale gamma of the NLOS excess [m]; unset: IQR heuristic
  /// kGaussianIqrPerSigma * sigma_m (about 0.20 m for sigma_m = 0.15 m).
  std::optional<double> nlos_scale_m;
  double nlos_weight = 0.2;   ///< prior NLOS probability w, in (0, 0.5)
  /// The receiver's NLOS indicator (DW1000/DW3000: RX level minus first-path
  /// power; Decawave APS006 takes > 6 dB as NLOS): a two-way range whose gap
  /// exceeds this (dB) gets the asymmetric model's NLOS component alone
  /// (nlos_component_loss.h) instead of the mixture. Only with the
  /// "asymmetric" model and ranges that carry both powers; +inf disables.
  double nlos_power_gap_db = 6.0;
  /// How a flagged range is modelled (range_model.h, docs/noise-models.md):
  /// the model's NLOS component alone (default, flagged_nlos_component), or
  /// the mixture with this larger prior NLOS weight (a flagged range with a
  /// small excess still fits the LOS core, and pulls the tag towards zero
  /// excess: under heavy NLOS with anchors overhead, 0.3-0.4 m low).
  double flagged_nlos_weight = 0.45;
  bool flagged_nlos_component = true;
  /// Half-Cauchy scale of a flagged range's excess [m]; unset: with the
  /// component, kDefaultFlaggedComponentScaleM widened for the ranging rate
  /// (flaggedComponentScaleAt, at most NlosComponentLoss::kMaxGamma LOS
  /// sigmas); with the mixture, nlos_scale_m. Fixed scales measured in
  /// docs/noise-models.md ("Figures behind the defaults").
  std::optional<double> flagged_nlos_scale_m;
  static constexpr double kDefaultFlaggedComponentScaleM = 1.0;
  /// Two-way ranging faster than this (Hz) widens the component's default
  /// scale by sqrt(rate / this) (flaggedComponentScaleAt; the Localizer
  /// applies it with the rate of the data tracking starts on). Why: an NLOS
  /// excess persists for seconds, so successive flagged ranges of an anchor
  /// share most of it, while the factors treat them as independent. The rule
  /// (about 2 m at 40 Hz) helps at high rates, while a fixed wide scale hurts
  /// at low ones, hence no widening up to 10 Hz; measured in
  /// docs/noise-models.md ("Figures behind the defaults"). 0: off.
  double flagged_scale_reference_hz = 10.0;

  /// gamma in metres after applying the default.
  double nlosScaleM() const { return nlos_scale_m.value_or(kGaussianIqrPerSigma * sigma_m); }
  /// The component's default scale for two-way ranging at rate_hz (m):
  /// kDefaultFlaggedComponentScaleM * sqrt(rate_hz / flagged_scale_reference_hz)
  /// above the reference rate, at most NlosComponentLoss::kMaxGamma LOS sigmas.
  double flaggedComponentScaleAt(double rate_hz) const {
    const double widen = flagged_scale_reference_hz > 0.0 && rate_hz > flagged_scale_reference_hz
                             ? std::sqrt(rate_hz / flagged_scale_reference_hz)
                             : 1.0;
    return std::min(kDefaultFlaggedComponentScaleM * widen, NlosComponentLoss::kMaxGamma * sigma_m);
  }
  /// The parameters a flagged range is modelled with: flagged weight and scale.
  RangeNoiseParams flagged() const {
    RangeNoiseParams f = *this;
    f.nlos_weight = flagged_nlos_weight;
    f.nlos_scale_m = flagged_nlos_scale_m.value_or(
        flagged_nlos_component ? flaggedComponentScaleAt(0.0) : nlosScaleM());
    return f;
  }
};

/// The NLOS component alone (nlos_component_loss.h) at params' sigma_m and
/// nlos_scale_m, shared like the asymmetric losses. Throws
/// std::invalid_argument naming a bad parameter.
std::shared_ptr<const NlosComponentLoss> makeNlosComponentLoss(const RangeNoiseParams& params);

/// params for another kind of measurement at sigma_m (TDoA, ultrasonic):
/// the same shape parameters, the NLOS scale back to its IQR default at sigma_m.
inline RangeNoiseParams withSigma(RangeNoiseParams params, double sigma_m) {
  params.sigma_m = sigma_m;
  params.nlos_scale_m.reset();
  return params;
}

/// Names accepted by makeRangeLoss, in documentation order.
const std::vector<std::string>& rangeLossNames();

/// "gaussian" | "huber" | "cauchy" | "asymmetric" (convolved NLOS component,
/// Ranging-IMU Fusion paper, eq. 7) | "asymmetric-half-cauchy" (Ranging-IMU Fusion paper, Fig. 2b). Never returns
/// null. Throws std::invalid_argument for an unknown name (the message lists the
/// valid ones) or an invalid parameter (the message names it).
RobustLossPtr makeRangeLoss(const std::string& name, const RangeNoiseParams& params = {});

}  // namespace rilo
