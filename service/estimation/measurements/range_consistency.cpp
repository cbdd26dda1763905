#include "estimation/measurements/range_consistency.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "estimation/measurements/range_time.h"

namespace rilo {

void RangeConsistencyParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("RangeConsistencyParams.") + field + " " + rule);
  };
  if (!(short_sigmas > 0.0 && std::isfinite(short_sigmas))) fail("short_sigmas", "must be finite and > 0");
  if (!(short_floor_m >= 0.0 && std::isfinite(short_floor_m))) fail("short_floor_m", "must be finite and >= 0");
  if (window < 1) fail("window", "must be >= 1");
  if (min_judged < 1 || min_judged > window) fail("min_judged", "must be in [1, window]");
  if (!(max_short_share > 0.0 && max_short_share <= 1.0)) fail("max_short_share", "must be in (0, 1]");
  if (max_age_ns < 0) fail("max_age_ns", "must be >= 0");
}

void FlaggedExcessParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("FlaggedExcessParams.") + field + " " + rule);
  };
  if (!(quantile >= 0.0 && quantile <= 1.0)) fail("quantile", "must be in [0, 1] (0: off)");
  if (min_ranges < 1 || min_ranges > RangeConsistencyMonitor::kFlaggedWindow) fail("min_ranges", "must be in [1, 200]");
  if (!(max_m >= 0.0 && std::isfinite(max_m))) fail("max_m", "must be finite and >= 0");
}

RangeConsistencyMonitor::RangeConsistencyMonitor(std::vector<Vec3> p_w_anchors, const Vec3& p_b_tag, double sigma_m,
                                                 std::int64_t same_state_window_ns, RangeConsistencyParams params,
                                                 double flag_gap_db, LosGapParams los_gap,
                                                 std::vector<TagLeverArm> tag_arms, NlosMemory nlos_memory)
    : p_w_anchors_(std::move(p_w_anchors)),
      p_b_tag_(p_b_tag),
      tag_arms_(std::move(tag_arms)),
      short_m_(std::max(params.short_sigmas * sigma_m, params.short_floor_m)),
      group_window_ns_(same_state_window_ns),
      params_(params),
      los_gap_(los_gap, sigma_m, flag_gap_db),
      nlos_memory_(std::move(nlos_memory)) {
  params_.validate();
  pending_.reserve(kMaxPending);
  window_.assign(static_cast<std::size_t>(params_.window), 0);
}

void RangeConsistencyMonitor::onRange(const RangeSample& range) noexcept {
  if (!params_.enabled || range.anchor_id >= p_w_anchors_.size()) return;
  if (pending_.size() == kMaxPending) pending_.erase(pending_.begin());  // no update for long: drop the oldest
  pending_.push_back(range);  // within the reserved capacity
}

double RangeConsistencyMonitor::residual(const RangeSample& range, const Pose3& T_w_b) const noexcept {
  const Vec3 p_w_tag = T_w_b.p + T_w_b.R * leverArmOf(tag_arms_, range.tag_id, p_b_tag_);
  return range.range_m - (p_w_tag - p_w_anchors_[range.anchor_id]).norm();
}

bool RangeConsistencyMonitor::judge(std::int64_t t_ns, const Pose3& T_w_b, const Vec3& v_w) noexcept {
  if (!params_.enabled) return true;
  std::size_t kept = 0;
  for (const RangeSample& r : pending_) {
    if (r.t_ns > t_ns + group_window_ns_) {
      pending_[kept++] = r;  // a later state's: wait for its update
      continue;
    }
    if (r.t_ns < t_ns - params_.max_age_ns) continue;  // too old to judge at this pose
    // The state's own ranges where its velocity takes the tag; an older state's at this pose.
    const double res = residual(r, r.t_ns > t_ns ? poseAtRangeTime(T_w_b, v_w, t_ns, r.t_ns) : T_w_b);
    const double gap_db = r.rssi_dbm - r.fp_power_dbm;
    // As RangeModel::flagsNlos; the flagged excess is the receiver's flags'
    // alone (RX-level flags take the component's mode, range_model.h).
    if (gap_db > los_gap_.threshold() && !r.fp_from_rx_level) {
      flagged_[static_cast<std::size_t>(flagged_next_)] = res;
      flagged_next_ = (flagged_next_ + 1) % kFlaggedWindow;
      if (flagged_filled_ < kFlaggedWindow) ++flagged_filled_;
    }
    // The calibration learns where the LOS gaps end from the ranges as the
    // mixture weighed them: a range the memory already took out pulled
    // weakly, and its larger residual in a LOS gap bin would lower the
    // threshold, flag more, and feed on itself (docs/noise-models.md, session 42).
    if (!r.nlos_from_memory) los_gap_.add(gap_db, res, r.fp_from_rx_level);
    nlos_memory_.judged(r.anchor_id, r.tag_id, r.t_ns, res);  // flagged ones too: a flag lasts while its ranges stay long
    const std::uint8_t is_short = res < -short_m_ ? 1 : 0;
    auto& slot = window_[static_cast<std::size_t>(next_)];
    if (filled_ == params_.window) short_in_window_ -= slot;
    else ++filled_;
    slot = is_short;
    short_in_window_ += is_short;
    next_ = (next_ + 1) % params_.window;
  }
  pending_.resize(kept);
  return !(filled_ >= params_.min_judged && shortShare() > params_.max_short_share);
}

double RangeConsistencyMonitor::flaggedQuantile(double q, int min_count) const noexcept {
  if (flagged_filled_ < min_count || flagged_filled_ == 0) return std::numeric_limits<double>::quiet_NaN();
  const auto n = static_cast<std::size_t>(flagged_filled_);
  std::copy(flagged_.begin(), flagged_.begin() + static_cast<std::ptrdiff_t>(n), scratch_.begin());
  const auto k = static_cast<std::size_t>(q * static_cast<double>(n - 1));
  std::nth_element(scratch_.begin(), scratch_.begin() + static_cast<std::ptrdiff_t>(k), scratch_.begin() + static_cast<std::ptrdiff_t>(n));
  return scratch_[k];
}

void RangeConsistencyMonitor::reset() noexcept {
  flagged_next_ = flagged_filled_ = 0;
  los_gap_.reset();
  pending_.clear();
  std::fill(window_.begin(), window_.end(), std::uint8_t{0});
  next_ = filled_ = short_in_window_ = 0;
  nlos_memory_.reset();
}

double RangeConsistencyMonitor::shortShare() const noexcept {
  return filled_ > 0 ? static_cast<double>(short_in_window_) / static_cast<double>(filled_) : 0.0;
}

}  // namespace rilo
