#include "evaluation/nlos_classification.h"

#include <algorithm>
#include <cstdlib>

namespace rilo {

NlosClassification classifyRanges(const std::vector<RangeSample>& ranges,
                                  const std::vector<RangeImuEstimator::TimedPose>& trajectory,
                                  const std::vector<Vec3>& p_w_anchors, const Vec3& p_b_tag, const RangeModel& model,
                                  double sigma_m, const NlosClassificationOptions& options) {
  NlosClassification out;
  if (trajectory.empty()) return out;
  std::size_t k = 0;  // first pose at or after the range (ranges in time order)
  for (const RangeSample& r : ranges) {
    if (r.anchor_id >= p_w_anchors.size()) continue;
    while (k < trajectory.size() && trajectory[k].t_ns < r.t_ns) ++k;
    std::size_t best = k < trajectory.size() ? k : trajectory.size() - 1;
    if (k > 0 && (k == trajectory.size() || r.t_ns - trajectory[k - 1].t_ns < trajectory[k].t_ns - r.t_ns)) best = k - 1;
    if (std::llabs(trajectory[best].t_ns - r.t_ns) > options.max_dt_ns) continue;
    const Pose3& T = trajectory[best].T_w_b;
    // States hold the ranges of up to range.same_state_window_s after them:
    // the body is where the walk between the two poses around the range puts
    // it at the range's time (the nearer pose's attitude; its turn over tens
    // of ms moves the antenna by millimetres).
    Vec3 p_w_b = T.p;
    if (k > 0 && k < trajectory.size() && trajectory[k].t_ns > trajectory[k - 1].t_ns) {
      const double u = static_cast<double>(r.t_ns - trajectory[k - 1].t_ns) /
                       static_cast<double>(trajectory[k].t_ns - trajectory[k - 1].t_ns);
      p_w_b = (1.0 - u) * trajectory[k - 1].T_w_b.p + u * trajectory[k].T_w_b.p;
    }
    const Vec3& p_b_antenna = leverArmOf(options.tag_lever_arms, r.tag_id, p_b_tag);
    const double predicted_m = (T.R * p_b_antenna + p_w_b - p_w_anchors[r.anchor_id]).norm();
    const RangeTerm term = model.term(Measurement::of(r), sigma_m);
    const bool down =
        term.flagged_nlos || term.loss->weight((term.range_m - predicted_m) / term.sigma_m) < options.weight_threshold;
    ++out.ranges;
    out.downweighted += down;
    if (r.los == 0) {
      ++out.labelled_nlos;
      out.nlos_downweighted += down;
    } else if (r.los == 1) {
      ++out.labelled_los;
      out.los_downweighted += down;
    }
  }
  return out;
}

}  // namespace rilo
