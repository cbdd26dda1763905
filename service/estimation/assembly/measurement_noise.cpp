#include "estimation/assembly/measurement_noise.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "estimation/measurements/range_time.h"

namespace rilo {
namespace {

NoiseKindParams withNominal(NoiseKindParams k, double nominal_m) {
  k.nominal_sigma_m = nominal_m;
  k.sigma_min_m = std::min(k.sigma_min_m, nominal_m);
  k.sigma_max_m = std::max(k.sigma_max_m, nominal_m);
  return k;
}

}  // namespace

DynamicCovarianceParams dynamicCovarianceParamsFor(const RangeImuGraphParams& graph,
                                                   const DynamicCovarianceParams& params) {
  DynamicCovarianceParams p = params;
  p.range = withNominal(p.range, graph.range_noise.sigma_m);
  p.tdoa = withNominal(p.tdoa, graph.tdoa_sigma_m);
  p.ultrasonic = withNominal(p.ultrasonic, graph.ultrasonic_sigma_m);
  return p;
}

MeasurementNoise::MeasurementNoise(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph,
                                   const DynamicCovarianceOptions& options)
    : p_w_anchors_(std::move(p_w_anchors)),
      p_w_ultrasonic_(graph.p_w_ultrasonic),
      p_b_tag_(graph.p_b_tag),
      p_b_ultrasonic_(graph.p_b_ultrasonic),
      tag_arms_(graph.tag_lever_arms),
      sigma_range_m_(graph.range_noise.sigma_m),
      sigma_tdoa_m_(graph.tdoa_sigma_m),
      sigma_ultrasonic_m_(graph.ultrasonic_sigma_m) {
  if (graph.tdoa_gap_excess.enabled && graph.tdoa_nlos_indicator) gap_excess_.emplace(graph.tdoa_gap_excess);
  if (!options.enabled && !gap_excess_) return;
  if (options.max_pending < 1) throw std::invalid_argument("DynamicCovarianceOptions.max_pending must be >= 1");
  max_pending_ = options.max_pending;
  pending_.reserve(max_pending_);
  if (!options.enabled) return;
  cov_.emplace(dynamicCovarianceParamsFor(graph, options.params));
  dynamic_kind_[static_cast<std::size_t>(Measurement::Kind::kRange)] = options.range;
  dynamic_kind_[static_cast<std::size_t>(Measurement::Kind::kTdoa)] = options.tdoa;
  dynamic_kind_[static_cast<std::size_t>(Measurement::Kind::kUltrasonic)] = options.ultrasonic;
}

double MeasurementNoise::nominalSigma(Measurement::Kind kind) const {
  switch (kind) {
    case Measurement::Kind::kTdoa: return sigma_tdoa_m_;
    case Measurement::Kind::kUltrasonic: return sigma_ultrasonic_m_;
    case Measurement::Kind::kRange: break;
  }
  return sigma_range_m_;
}

NoiseKey MeasurementNoise::keyOf(const Measurement& m) {
  switch (m.kind) {
    case Measurement::Kind::kTdoa: return NoiseKey::tdoa(m.anchor, m.anchor_b);
    case Measurement::Kind::kUltrasonic: return NoiseKey::ultrasonic(m.anchor);
    case Measurement::Kind::kRange: break;
  }
  return NoiseKey::range(m.anchor);
}

double MeasurementNoise::sigma(const Measurement& m) const {
  return dynamicKind(m.kind) ? cov_->sigma(keyOf(m)) : nominalSigma(m.kind);
}

double MeasurementNoise::predict(const Measurement& m, const Pose3& T_w_b) const {
  switch (m.kind) {
    case Measurement::Kind::kTdoa: {
      const Vec3 p_w_tag = T_w_b.R * p_b_tag_ + T_w_b.p;
      return (p_w_tag - p_w_anchors_.at(m.anchor_b)).norm() - (p_w_tag - p_w_anchors_.at(m.anchor)).norm();
    }
    case Measurement::Kind::kUltrasonic:
      return (T_w_b.R * p_b_ultrasonic_ + T_w_b.p - p_w_ultrasonic_.at(m.anchor)).norm();
    case Measurement::Kind::kRange: break;
  }
  return (T_w_b.R * leverArmOf(tag_arms_, m.tag, p_b_tag_) + T_w_b.p - p_w_anchors_.at(m.anchor)).norm();
}

void MeasurementNoise::count(CovarianceUpdate u) {
  if (u == CovarianceUpdate::kUpdated || u == CovarianceUpdate::kWarmingUp) ++fed_;
}

double MeasurementNoise::predictAt(const Pending& p, const Pose3& T_w_b, const Vec3& v_w) const {
  // As the factors predict them: where the state's velocity takes the tag by the measurement's time (RangeTimeOffset).
  return predict(p.m, poseAtRangeTime(T_w_b, v_w, p.state_t_ns, p.m.t_ns));
}

void MeasurementNoise::notePrediction(std::uint64_t state_index, std::int64_t state_t_ns, const Measurement& m,
                                      const Pose3& T_w_b_predicted, const Vec3& v_w_predicted) {
  if (!learnsFrom(m.kind)) return;
  if (!pending_.empty() && pending_index_ != state_index) pending_.clear();
  pending_index_ = state_index;
  if (pending_.size() >= max_pending_) {
    ++overflow_;
    return;
  }
  Pending p{m, 0.0, state_t_ns};
  p.innovation_m = m.value_m - predictAt(p, T_w_b_predicted, v_w_predicted);
  pending_.push_back(p);
}

void MeasurementNoise::notePostFit(std::uint64_t state_index, const Pose3& T_w_b_updated, const Vec3& v_w_updated) {
  if (pending_.empty() || pending_index_ != state_index) return;
  for (const Pending& p : pending_) {
    const double e_post = p.m.value_m - predictAt(p, T_w_b_updated, v_w_updated);
    if (gap_excess_ && p.m.kind == Measurement::Kind::kTdoa) gap_excess_->add(p.m.power_gap_db, p.m.power_gap_b_db, e_post);
    if (!dynamicKind(p.m.kind)) continue;
    const double product = p.innovation_m * e_post;
    const double r = product > 0.0 ? std::copysign(std::sqrt(product), p.innovation_m) : 0.0;
    count(cov_->update(keyOf(p.m), r));
  }
  pending_.clear();
}

void MeasurementNoise::noteInnovation(const Measurement& m, double innovation_m, double predicted_var_m2) {
  if (!dynamicKind(m.kind)) return;
  count(cov_->update(keyOf(m), innovation_m, std::max(0.0, predicted_var_m2)));
}

}  // namespace rilo
