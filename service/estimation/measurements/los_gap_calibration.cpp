#include "estimation/measurements/los_gap_calibration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo {

void LosGapParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("LosGapParams.") + field + " " + rule);
  };
  if (!(bin_db > 0.0 && std::isfinite(bin_db))) fail("bin_db", "must be finite and > 0");
  if (!(min_gap_db >= bin_db && std::isfinite(min_gap_db))) fail("min_gap_db", "must be finite and >= bin_db");
  if (reference_ranges < 1) fail("reference_ranges", "must be >= 1");
  if (min_bin_ranges < 1 || min_bin_ranges > LosGapCalibrator::kPerBin) fail("min_bin_ranges", "must be in [1, 128]");
  if (!(excess_sigmas > 0.0 && std::isfinite(excess_sigmas))) fail("excess_sigmas", "must be finite and > 0");
  if (recompute_every < 1) fail("recompute_every", "must be >= 1");
}

LosGapCalibrator::LosGapCalibrator(LosGapParams params, double sigma_m, double max_gap_db)
    : params_(params), delta_m_(params.excess_sigmas * sigma_m), max_gap_db_(max_gap_db), threshold_db_(max_gap_db),
      reference_m_(std::numeric_limits<double>::quiet_NaN()) {
  params_.validate();
  if (!(sigma_m > 0.0 && std::isfinite(sigma_m))) throw std::invalid_argument("LosGapCalibrator: sigma_m must be finite and > 0");
  if (std::isnan(max_gap_db)) throw std::invalid_argument("LosGapCalibrator: max_gap_db must not be NaN");
  table_.bin_db = params_.bin_db;
  if (params_.enabled && std::isfinite(max_gap_db) && max_gap_db > params_.min_gap_db)
    bins_used_ = std::min(kBins, static_cast<int>(std::ceil(max_gap_db / params_.bin_db)));
}

void LosGapCalibrator::add(double gap_db, double residual_m) noexcept {
  // Bins are (lo, hi], as the flag is gap > threshold: a range on a learnt
  // edge is in the bin below it. Checked before the cast (NaN fails too).
  if (bins_used_ == 0 || !(gap_db >= 0.0 && gap_db <= bins_used_ * params_.bin_db) || !std::isfinite(residual_m)) return;
  const int b = std::max(0, GapExcessTable::binOf(gap_db, params_.bin_db));  // a gap of 0 is in bin 0
  if (b >= bins_used_) return;
  residuals_[b][next_[b]] = residual_m;
  next_[b] = (next_[b] + 1) % kPerBin;
  if (filled_[b] < kPerBin) ++filled_[b];
  if (++since_recompute_ >= params_.recompute_every) recompute();
}

double LosGapCalibrator::scratchMedian(int n) const noexcept {
  const auto mid = scratch_.begin() + n / 2;
  std::nth_element(scratch_.begin(), mid, scratch_.begin() + n);
  return *mid;
}

void LosGapCalibrator::recompute() noexcept {
  since_recompute_ = 0;
  // The reference: bins whose upper edge is at most min_gap_db, pooled.
  int n = 0, b = 0;
  for (; b < bins_used_ && (b + 1) * params_.bin_db <= params_.min_gap_db + 1e-9; ++b) {
    std::copy_n(residuals_[b].begin(), filled_[b], scratch_.begin() + n);
    n += filled_[b];
  }
  threshold_db_ = max_gap_db_;
  table_.clear();
  if (n < params_.reference_ranges) {
    reference_m_ = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  reference_m_ = scratchMedian(n);
  bool stepped = false;
  for (; b < bins_used_; ++b) {
    if (filled_[b] < params_.min_bin_ranges) continue;
    std::copy_n(residuals_[b].begin(), filled_[b], scratch_.begin());
    const double excess_m = scratchMedian(filled_[b]) - reference_m_;
    table_.excess_m[static_cast<std::size_t>(b)] = std::max(0.0, excess_m);
    if (!stepped && excess_m > delta_m_) {
      threshold_db_ = std::min(max_gap_db_, std::max(params_.min_gap_db, b * params_.bin_db));
      stepped = true;
    }
  }
}

void LosGapCalibrator::reset() noexcept {
  next_.fill(0);
  filled_.fill(0);
  since_recompute_ = 0;
  threshold_db_ = max_gap_db_;
  reference_m_ = std::numeric_limits<double>::quiet_NaN();
  table_.clear();
}

}  // namespace rilo
