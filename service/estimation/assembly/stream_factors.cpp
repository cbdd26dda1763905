// The factors a state of the graph stream gets besides its IMU factor: where a
// measurement becomes a factor (addRangeFactors: a two-way range, a TDoA row
// or an ultrasonic range, with the sigma and loss its model gives), the motion
// priors (height band, vertical speed, zero velocity at a standstill), and the
// anchors' survey priors when anchors are variables. The rest of the stream
// (planning states, preintegrating, emitting) is range_imu_graph_stream.cpp.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <utility>

#include "estimation/assembly/range_imu_graph_stream.h"
#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/factors/tdoa_factor.h"
#include "estimation/factors/ultrasonic_factor.h"
#include "estimation/noise/weighted_loss.h"

namespace rilo {
namespace {

/// A factor marked as a motion prior (Factor::markMotionPrior).
template <class F, class... Args>
FactorPtr motionPrior(Args&&... args) {
  auto f = std::make_shared<F>(std::forward<Args>(args)...);
  f->markMotionPrior();
  return f;
}

}  // namespace

void RangeImuGraphStream::addMotionPriors(std::uint64_t i, std::int64_t interval_ns, GraphIncrement& inc) const {
  const HeightBand& band = params_.height_band;
  if (band.enabled) {
    inc.factors.add(motionPrior<HeightBandFactor>(sym::X(i), band.minZ() - params_.p_b_tag.z(),
                                                  band.maxZ() - params_.p_b_tag.z(), band.sigma_m));
  }
  if (params_.vertical_speed_sigma_m_s > 0.0) {
    // Horizontal speed is free (1e4 m/s std-dev); only v_z is held near zero.
    const double sigma = verticalSpeedPriorSigma(params_, interval_ns);
    inc.factors.add(motionPrior<PriorVec3Factor>(sym::V(i), Vec3::Zero(), Vec3(1e4, 1e4, sigma)));
  }
}

void RangeImuGraphStream::addCarryHold(std::uint64_t i, std::int64_t interval_ns, GraphIncrement& inc) const {
  const HeightBand& band = params_.height_band;
  if (!band.enabled || !(band.hold_sigma_m > 0.0)) return;
  const double interval_s = std::max(1e-3, 1e-9 * static_cast<double>(interval_ns));
  const double z_m = carry_height_.heightM() - params_.p_b_tag.z();  // body height of an upright wearer
  inc.factors.add(motionPrior<HeightBandFactor>(sym::X(i), z_m, z_m, band.hold_sigma_m / std::sqrt(interval_s)));
}

double RangeImuGraphStream::verticalWeightOf(const Measurement& m, double* sine) const {
  *sine = 0.0;
  const HeightBand& band = params_.height_band;
  if (!band.enabled || m.kind != Measurement::Kind::kRange) return 1.0;
  // From the measured range and the band's middle: a fact of the
  // measurement, not of a prediction (a batch window's states are
  // dead-reckoned while the stream runs).
  const double dz_m = band.midZ() - p_w_anchors_[m.anchor].z();
  *sine = dz_m / std::max({std::abs(dz_m), m.value_m, 1e-3});
  if (!band.range_lever) return 1.0;
  const double s0 = params_.range_noise.sigma_m / (0.5 * (band.max_height_m - band.min_height_m));
  const double u = std::clamp((std::abs(*sine) - s0) / s0, 0.0, 1.0);
  return u * u * (3.0 - 2.0 * u);  // smoothstep from s0 to 2 s0
}

void RangeImuGraphStream::noteHeightEvidence(std::uint64_t i, const Measurement& m) {
  if (!options_.learn_carry_height || m.kind != Measurement::Kind::kRange) return;
  double sine = 0.0;
  const double w = verticalWeightOf(m, &sine);
  if (w == 0.0) return;
  const double sigma_m = noise_.sigma(m);
  if (range_model_.term(m, sigma_m).flagged_nlos) return;  // the NLOS component's weak pull is no height evidence
  const double info = w * sine / sigma_m;
  carry_height_.addEvidence(i, info * info);
}

bool RangeImuGraphStream::addStandstillPrior(std::uint64_t i, std::int64_t t_prev_ns, std::int64_t t_ns,
                                             const Vec3& v_w_prev, GraphIncrement& inc) const {
  if (params_.zero_velocity_sigma_m_s <= 0.0 || !standstill_.stillFor(t_prev_ns, t_ns, v_w_prev)) return false;
  const double sigma = standstillPriorSigma(params_.zero_velocity_sigma_m_s, t_ns - t_prev_ns);
  inc.factors.add(motionPrior<PriorVec3Factor>(sym::V(i), Vec3::Zero(), Vec3(Vec3::Constant(sigma))));
  return true;
}

Key RangeImuGraphStream::uwbAnchorKey(std::uint32_t id, GraphIncrement& inc) const {
  const Key l = sym::L(id);
  if (!anchor_in_graph_[id] && !inc.values.exists(l)) {
    inc.values.insert(l, p_w_anchors_[id]);
    inc.new_anchor_keys.push_back(l);
  }
  return l;
}

void RangeImuGraphStream::addRangeFactors(std::size_t first, std::size_t n, std::uint64_t state,
                                          std::int64_t state_t_ns, GraphIncrement& inc) const {
  const bool vars = params_.anchors_as_variables;
  const Key x = sym::X(state);
  for (std::size_t k = first; k < first + n; ++k) {
    const Measurement& m = ranges_[k];
    const double sigma_m = tdoa_model_.vouchedLos(m) ? noise_.nominalSigma(m.kind) : noise_.sigma(m);
    // A measurement later than its state sees the tag moved on by the state's velocity.
    std::optional<RangeTimeOffset> offset;
    if (m.t_ns != state_t_ns) offset = RangeTimeOffset{sym::V(state), 1e-9 * static_cast<double>(m.t_ns - state_t_ns)};
    switch (m.kind) {
      case Measurement::Kind::kRange: {
        const RangeTerm t = range_model_.term(m, sigma_m);
        const Vec3& p_b_tag = params_.leverArm(m.tag);
        // The anchor's ranges that share this one's error count as one (range_repeats.h).
        const double repeats = range_repeats_.repeats(m.anchor, m.tag);
        const RobustLossPtr loss = repeats > 1.0 ? std::make_shared<WeightedLoss>(t.loss, 1.0 / repeats) : t.loss;
        auto f = vars ? std::make_shared<RangeFactor>(x, uwbAnchorKey(m.anchor, inc), t.range_m, t.sigma_m, p_b_tag,
                                                      loss, offset)
                      : std::make_shared<RangeFactor>(x, p_w_anchors_[m.anchor], t.range_m, t.sigma_m, p_b_tag, loss,
                                                      offset);
        double sine = 0.0;
        const double w = verticalWeightOf(m, &sine);
        if (w < 1.0) f->setVerticalWeight(w, params_.height_band.midZ() - p_w_anchors_[m.anchor].z());
        inc.factors.add(std::move(f));
        break;
      }
      case Measurement::Kind::kTdoa: {
        // The packets' learnt NLOS excess off the difference, before the
        // model orients the row (it may swap a and b and negate the value).
        Measurement corrected = m;
        corrected.value_m -= noise_.tdoaExcessCorrection(m);
        const TdoaTerm t = tdoa_model_.term(corrected, sigma_m);
        if (vars) {
          const Key a = uwbAnchorKey(t.anchor_a, inc);
          inc.factors.emplace<TdoaFactor>(x, a, uwbAnchorKey(t.anchor_b, inc), t.value_m, t.sigma_m, params_.p_b_tag,
                                          t.loss, offset);
        } else {
          inc.factors.emplace<TdoaFactor>(x, p_w_anchors_[t.anchor_a], p_w_anchors_[t.anchor_b], t.value_m, t.sigma_m,
                                          params_.p_b_tag, t.loss, offset);
        }
        break;
      }
      case Measurement::Kind::kUltrasonic:
        inc.factors.emplace<UltrasonicFactor>(x, params_.p_w_ultrasonic[m.anchor], m.value_m, sigma_m,
                                              params_.p_b_ultrasonic, std::nullopt, ultrasonic_loss_, offset);
        break;
    }
    ++inc.range_factors;
  }
}

void RangeImuGraphStream::addAnchorPriors(GraphIncrement& inc) const {
  for (Key l : inc.new_anchor_keys) {
    inc.factors.emplace<PriorVec3Factor>(l, p_w_anchors_[keyIndex(l)], Vec3(Vec3::Constant(params_.anchor_sigma_m)));
  }
}

void RangeImuGraphStream::commitAnchors(const GraphIncrement& inc) {
  for (Key l : inc.new_anchor_keys) anchor_in_graph_[keyIndex(l)] = true;
}

}  // namespace rilo
