#include "estimation/measurements/tdoa_model.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

/// A flagged packet's path is NLOS more often than not: the NLOS tail at the
/// receiver's flagged prior weight (RangeNoiseParams::flagged_nlos_weight, as
/// a flagged two-way range's mixture), its scale the IQR default at sigma_m.
/// 0.2 -> 0.45 took the sliding window on the six TDoA sims from 0.252 to
/// 0.234 m online RMSE (docs/noise-models.md).
RangeNoiseParams flaggedNoise(const RangeNoiseParams& noise, double sigma_m) {
  RangeNoiseParams p = withSigma(noise, sigma_m);
  p.nlos_weight = noise.flagged_nlos_weight;
  return p;
}

}  // namespace

TdoaModel::TdoaModel(const TdoaModelParams& params, const RangeNoiseParams& noise)
    : loss_(makeRangeLoss(params.loss, withSigma(noise, params.sigma_m))),
      flagged_loss_(makeRangeLoss(params.flagged_loss, flaggedNoise(noise, params.sigma_m))),
      gap_db_(noise.nlos_power_gap_db),
      both_factor_(params.both_flagged_sigma_factor),
      one_factor_(params.one_flagged_sigma_factor),
      use_indicator_(params.use_indicator),
      max_gap_db_(params.max_power_gap_db) {
  if (!(std::isfinite(both_factor_) && both_factor_ >= 1.0)) {
    throw std::invalid_argument("tdoa both_flagged_sigma_factor must be finite and >= 1, got " +
                                std::to_string(both_factor_));
  }
  if (!(std::isfinite(one_factor_) && one_factor_ >= 1.0)) {
    throw std::invalid_argument("tdoa one_flagged_sigma_factor must be finite and >= 1, got " +
                                std::to_string(one_factor_));
  }
  if (!(max_gap_db_ >= 0.0)) {
    throw std::invalid_argument("tdoa max_power_gap_db must be >= 0 (dB) or +inf to disable, got " +
                                std::to_string(max_gap_db_));
  }
  if (std::isnan(gap_db_)) {
    throw std::invalid_argument("range_noise.nlos_power_gap_db must be a number (dB) or +inf to disable, got NaN");
  }
}

int TdoaModel::flaggedPackets(const Measurement& m) const {
  if (m.kind != Measurement::Kind::kTdoa) return 0;
  return (flagged(m.power_gap_db) ? 1 : 0) + (flagged(m.power_gap_b_db) ? 1 : 0);
}

double TdoaModel::symmetricSigma(const Measurement& m, double sigma_m) const {
  const int n = flaggedPackets(m);
  return n == 2 ? sigma_m * both_factor_ : n == 1 ? sigma_m * one_factor_ : sigma_m;
}

TdoaTerm TdoaModel::term(const Measurement& m, double sigma_m) const {
  TdoaTerm t{m.anchor, m.anchor_b, m.value_m, sigma_m, loss_, flaggedPackets(m), false};
  if (t.flagged_packets == 2) {
    t.sigma_m = sigma_m * both_factor_;
  } else if (t.flagged_packets == 1) {
    t.loss = flagged_loss_;
    if (flagged(m.power_gap_db)) {  // a's packet is the late one: make it b
      t.anchor_a = m.anchor_b;
      t.anchor_b = m.anchor;
      t.value_m = -m.value_m;
      t.reversed = true;
    }
  }
  return t;
}

}  // namespace rilo
