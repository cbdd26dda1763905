#include "rilod/range_trust_monitor.h"

#include <algorithm>

#include "estimation/measurements/range_time.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {

RangeTrustMonitor::RangeTrustMonitor(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph)
    : p_w_anchors_(std::move(p_w_anchors)),
      loss_(makeRangeLoss(graph.range_loss, graph.range_noise)),
      sigma_m_(graph.range_noise.sigma_m),
      p_b_tag_(graph.p_b_tag),
      group_window_ns_(graph.same_state_window_ns) {
  pending_.reserve(kMaxPending);
  verdicts_.reserve(kMaxPending);
}

void RangeTrustMonitor::onRange(const RangeSample& range) noexcept {
  if (range.anchor_id >= p_w_anchors_.size()) {
    ++rejected_;
    return;
  }
  if (pending_.size() == kMaxPending) {  // no update for a long while: forget the oldest
    pending_.erase(pending_.begin());
    ++unjudged_;
  }
  pending_.push_back(range);  // within the reserved capacity
}

namespace {

double predictedRange(const Vec3& p_w_anchor, const Vec3& p_b_tag, const Pose3& T_w_b) noexcept {
  return (T_w_b.p + T_w_b.R * p_b_tag - p_w_anchor).norm();
}

}  // namespace

double RangeTrustMonitor::weight(const RangeSample& range, const Pose3& T_w_b) const noexcept {
  const double predicted_m = predictedRange(p_w_anchors_[range.anchor_id], p_b_tag_, T_w_b);
  return loss_->weight((range.range_m - predicted_m) / sigma_m_);
}

std::uint64_t RangeTrustMonitor::judge(const StateEstimate& latest) noexcept {
  std::uint64_t rejected_now = 0;
  std::size_t kept = 0;
  verdicts_.clear();
  for (const RangeSample& r : pending_) {
    if (r.t_ns > latest.t_ns + group_window_ns_) {
      pending_[kept++] = r;  // a later state's: wait for its update
    } else if (r.t_ns < latest.t_ns) {
      ++unjudged_;  // an older state's, absorbed in the same update
    } else {
      ++judged_;
      const double predicted_m = predictedRange(p_w_anchors_[r.anchor_id], p_b_tag_,
                                                poseAtRangeTime(latest.T_w_b, latest.v_w, latest.t_ns, r.t_ns));
      const double w = loss_->weight((r.range_m - predicted_m) / sigma_m_);
      if (!(w >= kTrustedWeight)) ++rejected_now;
      verdicts_.push_back({r.anchor_id, r.range_m, predicted_m, w, r.t_ns - latest.t_ns});  // within the reserved capacity
    }
  }
  pending_.resize(kept);
  rejected_ += rejected_now;
  return rejected_now;
}

}  // namespace rilo
