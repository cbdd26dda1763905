#include "evaluation/trajectory_metrics.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>
#include <string>

namespace rilo {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

void checkRpeParams(const RpeParams& p) {
  if (!(p.delta > 0.0) || !std::isfinite(p.delta)) {
    throw std::invalid_argument("rpe: delta must be > 0 and finite, got " + std::to_string(p.delta));
  }
  if (!(p.rel_tol >= 0.0 && p.rel_tol < 1.0)) {
    throw std::invalid_argument("rpe: rel_tol must be in [0, 1), got " + std::to_string(p.rel_tol));
  }
}

void checkTimeOrder(const TumTrajectory& estimate) {
  for (std::size_t k = 1; k < estimate.size(); ++k) {
    if (estimate[k].t_ns <= estimate[k - 1].t_ns) {
      throw std::invalid_argument("rpe: estimate times must strictly increase (pose " + std::to_string(k) + ")");
    }
  }
}

}  // namespace

PoseAssociation associateByTime(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                std::int64_t max_dt_ns) {
  if (max_dt_ns < 0) throw std::invalid_argument("associateByTime: max_dt_ns must be >= 0");
  PoseAssociation out;
  out.pairs.reserve(estimate.size());
  for (std::size_t k = 0; k < estimate.size(); ++k) {
    const std::int64_t t_ns = estimate[k].t_ns;
    auto it = std::lower_bound(truth.begin(), truth.end(), t_ns,
                               [](const GroundTruthPose& g, std::int64_t t) { return g.t_ns < t; });
    // Nearest in time; a tie goes to the later pose (`it`).
    if (it != truth.begin() &&
        (it == truth.end() || std::abs(std::prev(it)->t_ns - t_ns) < std::abs(it->t_ns - t_ns))) {
      --it;
    }
    if (it == truth.end() || std::abs(it->t_ns - t_ns) > max_dt_ns) {
      out.unmatched.push_back(k);
      continue;
    }
    out.pairs.emplace_back(k, static_cast<std::size_t>(it - truth.begin()));
    out.max_abs_dt_ns = std::max(out.max_abs_dt_ns, std::abs(it->t_ns - t_ns));
  }
  return out;
}

PositionErrorStats absolutePositionError(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                         const PoseAssociation& association) {
  std::vector<Vec3> p_est, p_true;
  p_est.reserve(association.pairs.size());
  p_true.reserve(association.pairs.size());
  for (const auto& [e, g] : association.pairs) {
    p_est.push_back(estimate.at(e).T_w_b.p);
    p_true.push_back(truth.at(g).p_w_b);
  }
  return positionErrorStats(p_est, p_true);
}

PositionErrorStats positionErrorAgainst(const std::vector<RangeImuEstimator::TimedPose>& poses,
                                        const std::vector<GroundTruthPose>& truth, std::int64_t max_dt_ns) {
  return absolutePositionError(poses, truth, associateByTime(poses, truth, max_dt_ns));
}

double trackedShare(const std::vector<RangeImuEstimator::TimedPose>& poses, std::int64_t t0_ns, std::int64_t t1_ns,
                    std::int64_t max_age_ns) {
  if (max_age_ns < 0) throw std::invalid_argument("trackedShare: max_age_ns must be >= 0");
  if (t1_ns <= t0_ns) return 0.0;
  std::int64_t covered = 0;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    if (k > 0 && poses[k].t_ns < poses[k - 1].t_ns) {
      throw std::invalid_argument("trackedShare: poses out of time order at index " + std::to_string(k));
    }
    // Pose k is the newest from its time until the next pose (or for ever).
    const std::int64_t from = std::max(poses[k].t_ns, t0_ns);
    // (no overflow for any max_age_ns: the sum is formed only when below t1)
    std::int64_t to = t1_ns - poses[k].t_ns <= max_age_ns ? t1_ns : poses[k].t_ns + max_age_ns;
    if (k + 1 < poses.size()) to = std::min(to, poses[k + 1].t_ns);
    to = std::min(to, t1_ns);
    if (to > from) covered += to - from;
  }
  return static_cast<double>(covered) / static_cast<double>(t1_ns - t0_ns);
}

std::vector<double> groundTruthPathLength(const std::vector<GroundTruthPose>& truth) {
  std::vector<double> s(truth.size(), 0.0);
  for (std::size_t k = 1; k < truth.size(); ++k) s[k] = s[k - 1] + (truth[k].p_w_b - truth[k - 1].p_w_b).norm();
  return s;
}

std::vector<std::pair<std::size_t, std::size_t>> rpePairs(const TumTrajectory& estimate,
                                                          const std::vector<GroundTruthPose>& truth,
                                                          const PoseAssociation& association, const RpeParams& params) {
  checkRpeParams(params);
  checkTimeOrder(estimate);
  const auto& pairs = association.pairs;
  // Separation coordinate of each associated pose, non-decreasing along `pairs`.
  std::vector<double> key(pairs.size());
  if (params.unit == RpeDelta::kSeconds) {
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      key[k] = static_cast<double>(estimate.at(pairs[k].first).t_ns - estimate.at(pairs.front().first).t_ns) * 1e-9;
    }
  } else {
    const std::vector<double> s = groundTruthPathLength(truth);
    for (std::size_t k = 0; k < pairs.size(); ++k) key[k] = s.at(pairs[k].second);
  }
  const double tol = params.rel_tol * params.delta;
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t i = 0; i + 1 < pairs.size(); ++i) {
    const double target = key[i] + params.delta;
    const auto first = key.begin() + static_cast<std::ptrdiff_t>(i + 1);
    auto above = std::lower_bound(first, key.end(), target);
    std::size_t j = static_cast<std::size_t>(above - key.begin());
    if (above != first && (above == key.end() || target - *std::prev(above) < *above - target)) --j;
    if (j >= key.size()) continue;
    if (std::abs(key[j] - key[i] - params.delta) <= tol) out.emplace_back(i, j);
  }
  return out;
}

RelativePoseErrorStats relativePoseError(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                         const PoseAssociation& association, const RpeParams& params) {
  const auto pairs = rpePairs(estimate, truth, association, params);
  std::vector<double> e_trans, e_rot;
  e_trans.reserve(pairs.size());
  e_rot.reserve(pairs.size());
  for (const auto& [i, j] : pairs) {
    const auto [est_i, truth_i] = association.pairs[i];
    const auto [est_j, truth_j] = association.pairs[j];
    const Pose3 D_est = estimate[est_i].T_w_b.inverse().compose(estimate[est_j].T_w_b);
    const Pose3 D_truth = truth[truth_i].pose().inverse().compose(truth[truth_j].pose());
    e_trans.push_back((D_truth.p - D_est.p).norm());
    e_rot.push_back(so3::log(D_truth.R.transpose() * D_est.R).norm() * kRadToDeg);
  }
  RelativePoseErrorStats out;
  out.params = params;
  out.translation_m = errorStats(std::move(e_trans));
  out.rotation_deg = errorStats(std::move(e_rot));
  return out;
}

TrajectoryEvaluation evaluateTrajectory(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                        const EvaluationParams& params) {
  TrajectoryEvaluation out;
  out.estimate_poses = estimate.size();
  out.truth_poses = truth.size();
  out.association = associateByTime(estimate, truth, params.max_dt_ns);
  out.ape = absolutePositionError(estimate, truth, out.association);
  out.rpe_time = relativePoseError(estimate, truth, out.association, params.rpe_time);
  out.rpe_distance = relativePoseError(estimate, truth, out.association, params.rpe_distance);
  return out;
}

}  // namespace rilo
