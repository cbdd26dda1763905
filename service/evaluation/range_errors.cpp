#include "evaluation/range_errors.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "hal/recording/truth_lookup.h"

namespace rilo {
namespace {

std::int64_t toNs(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

double quantile(const std::vector<double>& sorted, double p) {
  const double at = p * static_cast<double>(sorted.size() - 1);
  const auto below = static_cast<std::size_t>(std::floor(at));
  const std::size_t above = std::min(below + 1, sorted.size() - 1);
  const double w = at - static_cast<double>(below);
  return (1.0 - w) * sorted[below] + w * sorted[above];
}

}  // namespace

RangeErrors rangeErrors(const Recording& recording, const RangeErrorOptions& options) {
  if (!(options.max_truth_gap_s > 0.0) || !std::isfinite(options.max_truth_gap_s)) {
    throw std::invalid_argument("rangeErrors: max_truth_gap_s must be finite and > 0, got " +
                                std::to_string(options.max_truth_gap_s));
  }
  if (!(options.radial_step_s > 0.0) || !std::isfinite(options.radial_step_s)) {
    throw std::invalid_argument("rangeErrors: radial_step_s must be finite and > 0, got " +
                                std::to_string(options.radial_step_s));
  }
  if (!std::isfinite(options.truth_shift_s) || std::abs(options.truth_shift_s) > 3600.0) {
    throw std::invalid_argument("rangeErrors: truth_shift_s must be finite and within +-3600 s, got " +
                                std::to_string(options.truth_shift_s));
  }
  if (recording.groundtruth.empty()) {
    throw std::invalid_argument("rangeErrors: the recording has no ground truth (groundtruth.csv)");
  }
  const TruthLookup truth(recording.groundtruth, toNs(options.max_truth_gap_s));
  const std::int64_t step_ns = toNs(options.radial_step_s);
  const std::int64_t shift_ns = toNs(options.truth_shift_s);
  RangeErrors out;
  out.errors.reserve(recording.ranges.size());
  for (const RangeSample& r : recording.ranges) {
    if (!std::isfinite(r.range_m)) {
      ++out.non_finite;
      continue;
    }
    const Anchor* anchor = recording.findAnchor(r.anchor_id);
    if (anchor == nullptr) {
      ++out.unknown_anchor;
      continue;
    }
    const std::optional<Vec3> p_b_tag = recording.findTagLeverArm(r.tag_id);
    if (!p_b_tag) {
      ++out.unknown_tag;
      continue;
    }
    // The true distance from the anchor to the antenna at time t (false outside the truth).
    auto distanceAt = [&](std::int64_t t_ns, double& d) {
      Mat3 R_w_b;
      Vec3 p_w_b;
      if (!truth.at(t_ns, R_w_b, p_w_b)) return false;
      d = (p_w_b + R_w_b * *p_b_tag - anchor->p_w_anchor).norm();
      return true;
    };
    RangeError e;
    const std::int64_t t_truth = r.t_ns - shift_ns;
    if (!distanceAt(t_truth, e.true_m)) {
      ++out.without_truth;
      continue;
    }
    e.t_ns = r.t_ns;
    e.anchor_id = r.anchor_id;
    e.tag_id = r.tag_id;
    e.range_m = r.range_m;
    e.error_m = r.range_m - e.true_m;
    e.los = r.los;
    double before = 0.0, after = 0.0;
    if (distanceAt(t_truth - step_ns, before) && distanceAt(t_truth + step_ns, after)) {
      e.radial_speed_m_s = (after - before) / (2.0 * options.radial_step_s);
    }
    out.errors.push_back(e);
  }
  return out;
}

RangeErrorStats summarizeRangeErrors(std::span<const RangeError> errors, double threshold_m) {
  if (!(threshold_m >= 0.0) || !std::isfinite(threshold_m)) {
    throw std::invalid_argument("summarizeRangeErrors: threshold_m must be finite and >= 0, got " +
                                std::to_string(threshold_m));
  }
  RangeErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  std::vector<double> sorted;
  sorted.reserve(errors.size());
  double sum = 0.0;
  std::size_t below = 0, above = 0;
  for (const RangeError& e : errors) {
    sorted.push_back(e.error_m);
    sum += e.error_m;
    below += e.error_m < -threshold_m ? 1 : 0;
    above += e.error_m > threshold_m ? 1 : 0;
  }
  std::sort(sorted.begin(), sorted.end());
  const double n = static_cast<double>(errors.size());
  s.mean_m = sum / n;
  s.p1_m = quantile(sorted, 0.01);
  s.p5_m = quantile(sorted, 0.05);
  s.median_m = quantile(sorted, 0.5);
  s.p95_m = quantile(sorted, 0.95);
  s.p99_m = quantile(sorted, 0.99);
  s.short_share = static_cast<double>(below) / n;
  s.long_share = static_cast<double>(above) / n;

  double sv = 0.0, se = 0.0;
  std::size_t m = 0;
  for (const RangeError& e : errors) {
    if (!std::isfinite(e.radial_speed_m_s)) continue;
    sv += e.radial_speed_m_s;
    se += e.error_m;
    ++m;
  }
  if (m >= 3) {
    const double mv = sv / static_cast<double>(m), me = se / static_cast<double>(m);
    double svv = 0.0, see = 0.0, sve = 0.0;
    for (const RangeError& e : errors) {
      if (!std::isfinite(e.radial_speed_m_s)) continue;
      const double dv = e.radial_speed_m_s - mv, de = e.error_m - me;
      svv += dv * dv;
      see += de * de;
      sve += dv * de;
    }
    if (svv > 0.0) s.radial_slope_s = sve / svv;
    if (svv > 0.0 && see > 0.0) s.radial_correlation = sve / std::sqrt(svv * see);
  }
  return s;
}

}  // namespace rilo
