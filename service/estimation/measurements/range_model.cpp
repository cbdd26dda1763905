#include "estimation/measurements/range_model.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo {

RangeModel::RangeModel(const std::string& loss_name, const RangeNoiseParams& noise)
    : loss_(makeRangeLoss(loss_name, noise)), gap_db_(noise.nlos_power_gap_db) {
  if (noise.flagged_nlos_scale_m && !(std::isfinite(*noise.flagged_nlos_scale_m) && *noise.flagged_nlos_scale_m > 0.0)) {
    throw std::invalid_argument("range_noise.flagged_nlos_scale_m must be finite and > 0 (m), got " +
                                std::to_string(*noise.flagged_nlos_scale_m));
  }
  if (!(std::isfinite(noise.flagged_scale_reference_hz) && noise.flagged_scale_reference_hz >= 0.0)) {
    throw std::invalid_argument("range_noise.flagged_scale_reference_hz must be finite and >= 0 (Hz; 0: off), got " +
                                std::to_string(noise.flagged_scale_reference_hz));
  }
  if (std::isnan(noise.nlos_power_gap_db)) {
    throw std::invalid_argument("range_noise.nlos_power_gap_db must be a number (dB) or +inf to disable, got NaN");
  }
  // Only the convolved asymmetric model has an NLOS component with a Gaussian
  // core (the half-Cauchy variant's is 0 below zero excess); the symmetric
  // models have none, so the indicator leaves them as configured.
  if (loss_name != "asymmetric" || !std::isfinite(gap_db_)) return;
  const RangeNoiseParams flagged = noise.flagged();  // validated by the factory
  if (noise.flagged_nlos_component) {
    component_ = makeNlosComponentLoss(flagged);
    flagged_loss_ = component_;
  } else {
    flagged_loss_ = makeRangeLoss(loss_name, flagged);
  }
}

RangeTerm RangeModel::term(const Measurement& m, double sigma_m) const {
  if (!flagsNlos(m)) return {m.value_m, sigma_m, loss_, false};
  // The gap's own bin, where the calibration measured one, else the site's;
  // a range flagged by its anchor's memory alone has neither.
  const bool by_memory_alone = !(m.power_gap_db > gap_db_);
  const double bin_excess_m =
      by_memory_alone ? std::numeric_limits<double>::quiet_NaN() : gap_excess_.at(m.power_gap_db);
  if (!component_) {
    const double site_m = m.gap_from_rx_level || by_memory_alone ? 0.0 : flagged_excess_m_;
    return {m.value_m - (std::isfinite(bin_excess_m) ? bin_excess_m : site_m), sigma_m, flagged_loss_, true};
  }
  // The site's flagged excess is learnt from the receiver's own flags; a
  // flag from the RX level takes the component's mode (Localizer::withRxLevelIndicator).
  const bool site_excess = excess_set_ && !m.gap_from_rx_level && !by_memory_alone;
  const double shift_m = std::isfinite(bin_excess_m) ? bin_excess_m
                         : site_excess              ? flagged_excess_m_
                                                    : component_->modeSigmas() * sigma_m;
  return {m.value_m - shift_m, sigma_m * component_->sigmaScale(), flagged_loss_, true};
}

}  // namespace rilo
