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
  if (!(rx_level_max_gap_db > 0.0)) fail("rx_level_max_gap_db", "must be > 0 (dB; beyond the bins it is clamped)");
}

LosGapCalibrator::LosGapCalibrator(LosGapParams params, double sigma_m, double max_gap_db)
    : params_(params), delta_m_(params.excess_sigmas * sigma_m), max_gap_db_(max_gap_db), threshold_db_(max_gap_db),
      reference_m_(std::numeric_limits<double>::quiet_NaN()) {
  params_.validate();
  if (!(sigma_m > 0.0 && std::isfinite(sigma_m))) throw std::invalid_argument("LosGapCalibrator: sigma_m must be finite and > 0");
  if (std::isnan(max_gap_db)) throw std::invalid_argument("LosGapCalibrator: max_gap_db must not be NaN");
  table_.bin_db = params_.bin_db;
  if (params_.enabled && std::isfinite(max_gap_db) && max_gap_db > params_.min_gap_db) {
    receiver_bins_ = std::min(kBins, static_cast<int>(std::ceil(max_gap_db / params_.bin_db)));
    const double top_db = std::min(std::max(max_gap_db, params_.rx_level_max_gap_db), kBins * params_.bin_db);
    bins_used_ = std::min(kBins, static_cast<int>(std::ceil(top_db / params_.bin_db)));
  }
}

double LosGapCalibrator::boundDb() const noexcept {
  if (since_receiver_gap_ < kNoReceiverGap) return max_gap_db_;
  return std::max(max_gap_db_, std::min(params_.rx_level_max_gap_db, bins_used_ * params_.bin_db));
}

void LosGapCalibrator::add(double gap_db, double residual_m, bool from_rx_level) noexcept {
  // Bins are (lo, hi], as the flag is gap > threshold: a range on a learnt
  // edge is in the bin below it. Checked before the cast (NaN fails too).
  // Any receiver gap, binned or not, keeps the configured bound (boundDb);
  // the receiver's own gaps are binned up to the configured threshold only.
  if (gap_db >= 0.0) {  // NaN fails
    if (!from_rx_level) since_receiver_gap_ = 0;
    else if (since_receiver_gap_ < kNoReceiverGap) ++since_receiver_gap_;
  }
  const int bins = from_rx_level ? bins_used_ : receiver_bins_;
  if (bins == 0 || !(gap_db >= 0.0 && gap_db <= bins * params_.bin_db) || !std::isfinite(residual_m)) return;
  const int b = std::max(0, GapExcessTable::binOf(gap_db, params_.bin_db));  // a gap of 0 is in bin 0
  if (b >= bins) return;
  residuals_[static_cast<std::size_t>(b)][static_cast<std::size_t>(next_[b])] = residual_m;
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
  const double bound_db = boundDb();
  threshold_db_ = max_gap_db_;
  table_.clear();
  if (n < params_.reference_ranges) {
    reference_m_ = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  reference_m_ = scratchMedian(n);
  // A bin that reaches past the configured threshold is "above" it (the
  // bound's rules); the table keeps the bins that start below it.
  const auto edge = [&](double lo_db) { return std::min(bound_db, std::max(params_.min_gap_db, lo_db)); };
  double pending_db = -1.0;  // lower edge of a bin with excess, waiting for the next filled bin (header)
  bool done = false;
  for (; b < bins_used_ && b * params_.bin_db < bound_db - 1e-9; ++b) {
    const double lo_db = b * params_.bin_db;
    const bool above_configured = (b + 1) * params_.bin_db > max_gap_db_ + 1e-9;
    if (filled_[b] < params_.min_bin_ranges) {
      if (above_configured && !done) {
        // No evidence past here: a waiting step stands alone, else the threshold stops at this bin.
        threshold_db_ = pending_db >= 0.0 ? edge(pending_db) : std::max(max_gap_db_, lo_db);
        done = true;
      }
      continue;
    }
    std::copy_n(residuals_[b].begin(), filled_[b], scratch_.begin());
    const double excess_m = scratchMedian(filled_[b]) - reference_m_;
    if (lo_db < max_gap_db_ - 1e-9) table_.excess_m[static_cast<std::size_t>(b)] = std::max(0.0, excess_m);
    if (done) continue;
    if (excess_m > delta_m_) {
      // Confirmed, or above the configured threshold: where excess shows, a rise stops.
      if (pending_db >= 0.0 || above_configured) {
        threshold_db_ = edge(pending_db >= 0.0 ? pending_db : lo_db);
        done = true;
      } else {
        pending_db = lo_db;
      }
    } else {
      pending_db = -1.0;
    }
  }
  if (done) return;
  // The last bin searched had excess: nothing after it to confirm it. Else
  // every bin up to the bound was LOS (or, below the configured threshold, unfilled): the bound.
  threshold_db_ = pending_db >= 0.0 ? edge(pending_db) : bound_db;
}

void LosGapCalibrator::reset() noexcept {
  next_.fill(0);
  filled_.fill(0);
  since_receiver_gap_ = kNoReceiverGap;
  since_recompute_ = 0;
  threshold_db_ = max_gap_db_;
  reference_m_ = std::numeric_limits<double>::quiet_NaN();
  table_.clear();
}

}  // namespace rilo
