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
  if (!(rx_level_max_gap_db > 0.0) || std::isnan(rx_level_max_gap_db) ||
      rx_level_max_gap_db > LosGapCalibrator::kBins * bin_db) {
    fail("rx_level_max_gap_db", "must be > 0 and within the bins (kBins * bin_db)");
  }
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
    const double top_db = std::max(max_gap_db, params_.rx_level_max_gap_db);
    bins_used_ = std::min(kBins, static_cast<int>(std::ceil(top_db / params_.bin_db)));
  }
}

double LosGapCalibrator::boundDb() const noexcept {
  return receiver_slots_ > 0 ? max_gap_db_ : std::max(max_gap_db_, params_.rx_level_max_gap_db);
}

void LosGapCalibrator::add(double gap_db, double residual_m, bool from_rx_level) noexcept {
  // Bins are (lo, hi], as the flag is gap > threshold: a range on a learnt
  // edge is in the bin below it. Checked before the cast (NaN fails too).
  // The receiver's own gaps are kept up to the configured threshold only.
  const int bins = from_rx_level ? bins_used_ : receiver_bins_;
  if (bins == 0 || !(gap_db >= 0.0 && gap_db <= bins * params_.bin_db) || !std::isfinite(residual_m)) return;
  const int b = std::max(0, GapExcessTable::binOf(gap_db, params_.bin_db));  // a gap of 0 is in bin 0
  if (b >= bins) return;
  const auto slot = static_cast<std::size_t>(next_[b]);
  const auto bin = static_cast<std::size_t>(b);
  if (filled_[b] == kPerBin && from_receiver_[bin][slot]) --receiver_slots_;  // overwritten
  residuals_[bin][slot] = residual_m;
  from_receiver_[bin][slot] = !from_rx_level;
  if (!from_rx_level) ++receiver_slots_;
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
  // Below the configured threshold an unfilled bin is passed over; above it
  // (RX-level gaps only, boundDb) the threshold rises only through bins that
  // showed they are LOS: filled, without excess.
  // A step needs the next filled bin's excess too (the last bin stands
  // alone): residuals are taken at the tracked pose, whose error projects
  // differently on the anchors that dominate each bin, and one bin's median
  // crossed the step by that alone (own halls without the column: the
  // threshold fell to 3-4 dB, deep in their LOS ranges, a quarter of the
  // time). Excess that begins grows with the gap, so two bins see it.
  bool stepped = false, raising = true;
  double pending_db = -1.0;  // lower edge of a bin with excess, waiting for the next filled bin
  for (; b < bins_used_ && b * params_.bin_db < bound_db - 1e-9; ++b) {
    const double lo_db = b * params_.bin_db;
    const bool above_configured = lo_db >= max_gap_db_ - 1e-9;
    if (filled_[b] < params_.min_bin_ranges) {
      if (above_configured && !stepped && raising) {
        // No evidence past here: a waiting step stands alone, else the threshold stops at this bin.
        threshold_db_ = pending_db >= 0.0 ? pending_db : std::max(max_gap_db_, lo_db);
        raising = false;
      }
      continue;
    }
    std::copy_n(residuals_[b].begin(), filled_[b], scratch_.begin());
    const double excess_m = scratchMedian(filled_[b]) - reference_m_;
    if (!above_configured) table_.excess_m[static_cast<std::size_t>(b)] = std::max(0.0, excess_m);
    if (stepped || !raising) continue;
    if (excess_m > delta_m_) {
      if (pending_db >= 0.0) {
        threshold_db_ = std::min(bound_db, std::max(params_.min_gap_db, pending_db));
        stepped = true;
      } else {
        pending_db = lo_db;
      }
    } else {
      pending_db = -1.0;
    }
  }
  if (!stepped && raising && pending_db >= 0.0) {  // the last bin searched: nothing after it to confirm
    threshold_db_ = std::min(bound_db, std::max(params_.min_gap_db, pending_db));
    stepped = true;
  }
  // Every bin up to the bound was filled and LOS: the bound.
  if (!stepped && raising) threshold_db_ = bound_db;
}

void LosGapCalibrator::reset() noexcept {
  next_.fill(0);
  filled_.fill(0);
  receiver_slots_ = 0;
  since_recompute_ = 0;
  threshold_db_ = max_gap_db_;
  reference_m_ = std::numeric_limits<double>::quiet_NaN();
  table_.clear();
}

}  // namespace rilo
