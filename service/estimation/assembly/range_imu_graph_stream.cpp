#include "estimation/assembly/range_imu_graph_stream.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "estimation/factors/imu_factor.h"
#include "estimation/factors/prior_factors.h"

namespace rilo {
namespace {

constexpr double kNsToS = 1e-9;

std::string ns(std::int64_t t_ns) { return std::to_string(t_ns); }

/// Integrates the zero-order-held IMU samples over [t_a, t_b] into pim,
/// advancing `cursor` (index of the sample in effect at t_a, or 0 if the first
/// sample is later: it is then held backwards) to the sample in effect at t_b.
template <class ImuSequence>
void integrateInterval(const ImuSequence& imu, std::size_t& cursor, std::int64_t t_a_ns, std::int64_t t_b_ns,
                       PreintegratedImu& pim) {
  std::int64_t t = t_a_ns;
  while (t < t_b_ns) {
    const std::int64_t t_next =
        cursor + 1 < imu.size() ? std::min(imu[cursor + 1].t_ns, t_b_ns) : t_b_ns;
    if (t_next > t) {
      pim.integrate(imu[cursor].accel_m_s2, imu[cursor].gyro_rad_s, static_cast<double>(t_next - t) * kNsToS);
      t = t_next;
    }
    if (cursor + 1 < imu.size() && imu[cursor + 1].t_ns <= t) ++cursor;
  }
}

/// t_from + floor(gap j / pieces), without forming gap * j (overflow on long gaps).
std::int64_t gapStateTime(std::int64_t t_from_ns, std::int64_t gap_ns, std::int64_t j, std::int64_t pieces) {
  return t_from_ns + (gap_ns / pieces) * j + (gap_ns % pieces) * j / pieces;
}

bool allFinite(const Pose3& T) { return T.R.allFinite() && T.p.allFinite(); }

}  // namespace

RangeImuGraphStream::RangeImuGraphStream(std::vector<Vec3> p_w_anchors, RangeImuGraphParams params,
                                         RangeImuStreamOptions options)
    : p_w_anchors_(std::move(p_w_anchors)),
      params_(std::move(params)),
      options_(options),
      range_model_(params_.range_loss, params_.range_noise),
      tdoa_model_(tdoaModelParams(params_), params_.range_noise),
      ultrasonic_loss_(makeRangeLoss(params_.ultrasonic_loss, withSigma(params_.range_noise, params_.ultrasonic_sigma_m))),
      pim_(params_.imu, ImuBias(), PreintegratedImu::CovarianceMode::kCombined),
      noise_(p_w_anchors_, params_, options_.dynamic_covariance),
      carry_height_(params_.height_band, options_.learn_carry_height),
      range_repeats_(p_w_anchors_.size(), options_.range_repeats),
      anchor_in_graph_(p_w_anchors_.size(), false),
      standstill_(params_.standstill, options.initial_imu_capacity),
      imu_(options.initial_imu_capacity),
      ranges_(64),
      plan_(64) {
  const std::string where = "RangeImuGraphStream: ";
  if (params_.same_state_window_ns < 0) throw std::invalid_argument(where + "same_state_window_ns must be >= 0");
  if (params_.max_state_interval_ns <= params_.same_state_window_ns) {
    throw std::invalid_argument(where + "max_state_interval_ns must exceed same_state_window_ns");
  }
  if (options_.max_range_wait_ns < params_.max_state_interval_ns) {
    throw std::invalid_argument(where + "max_range_wait_ns must be >= max_state_interval_ns");
  }
  if (options_.max_gap_ns < params_.max_state_interval_ns) {
    throw std::invalid_argument(where + "max_gap_ns must be >= max_state_interval_ns");
  }
  if (!(std::isfinite(params_.range_noise.sigma_m) && params_.range_noise.sigma_m > 0.0)) {
    throw std::invalid_argument(where + "range_noise.sigma_m must be positive and finite");
  }
  if (!params_.p_b_tag.allFinite()) throw std::invalid_argument(where + "p_b_tag must be finite");
  validateTagLeverArms(params_.tag_lever_arms, where.c_str());
  if (!(std::isfinite(params_.tdoa_sigma_m) && params_.tdoa_sigma_m > 0.0)) {
    throw std::invalid_argument(where + "tdoa_sigma_m must be positive and finite");
  }
  if (!(std::isfinite(params_.ultrasonic_sigma_m) && params_.ultrasonic_sigma_m > 0.0)) {
    throw std::invalid_argument(where + "ultrasonic_sigma_m must be positive and finite");
  }
  if (!params_.p_b_ultrasonic.allFinite()) throw std::invalid_argument(where + "p_b_ultrasonic must be finite");
  for (std::size_t a = 0; a < params_.p_w_ultrasonic.size(); ++a) {
    if (!params_.p_w_ultrasonic[a].allFinite()) {
      throw std::invalid_argument(where + "p_w_ultrasonic[" + std::to_string(a) + "] must be finite");
    }
  }
  params_.height_band.validate("RangeImuGraphStream: height_band");
  if (!(std::isfinite(params_.vertical_speed_sigma_m_s) && params_.vertical_speed_sigma_m_s >= 0.0)) {
    throw std::invalid_argument(where + "vertical_speed_sigma_m_s must be finite and >= 0");
  }
  if (!(std::isfinite(params_.vertical_speed_correlation_s) && params_.vertical_speed_correlation_s > 0.0)) {
    throw std::invalid_argument(where + "vertical_speed_correlation_s must be finite and > 0");
  }
  if (!(std::isfinite(params_.zero_velocity_sigma_m_s) && params_.zero_velocity_sigma_m_s >= 0.0)) {
    throw std::invalid_argument(where + "zero_velocity_sigma_m_s must be finite and >= 0");
  }
  if (params_.anchors_as_variables && !(std::isfinite(params_.anchor_sigma_m) && params_.anchor_sigma_m > 0.0)) {
    throw std::invalid_argument(where + "anchor_sigma_m must be positive and finite");
  }
  for (std::size_t a = 0; a < p_w_anchors_.size(); ++a) {
    if (!p_w_anchors_[a].allFinite()) throw std::invalid_argument(where + "p_w_anchors[" + std::to_string(a) + "] must be finite");
  }
}

GraphIncrement RangeImuGraphStream::start(std::int64_t t0_ns, const Pose3& T_w_b0_guess, const Vec3& v_w0_guess,
                                          const ImuBias& bias0_guess,
                                          const std::optional<StartCovariance>& covariance) {
  if (started_) throw std::logic_error("RangeImuGraphStream::start: already started");
  if (!allFinite(T_w_b0_guess) || !v_w0_guess.allFinite()) {
    throw std::invalid_argument("RangeImuGraphStream::start: T_w_b0_guess and v_w0_guess must be finite");
  }
  GraphIncrement inc;
  if (covariance) {
    // The factors check the blocks (symmetric, positive definite) and name them.
    inc.factors.add(std::make_shared<PriorPose3Factor>(
        sym::X(0), T_w_b0_guess, SqrtInformation<6>::fromCovariance(covariance->pose, "start covariance.pose")));
    inc.factors.add(std::make_shared<PriorVec3Factor>(
        sym::V(0), v_w0_guess, SqrtInformation<3>::fromCovariance(covariance->velocity, "start covariance.velocity")));
    inc.factors.add(std::make_shared<PriorBiasFactor>(
        sym::B(0), bias0_guess, SqrtInformation<6>::fromCovariance(covariance->bias, "start covariance.bias")));
  } else {
    inc.factors.emplace<PriorPose3Factor>(sym::X(0), T_w_b0_guess, params_.first_pose_sigmas);
    inc.factors.emplace<PriorVec3Factor>(sym::V(0), v_w0_guess, Vec3(Vec3::Constant(params_.first_velocity_sigma_m_s)));
    Vec6 bias_sigmas;
    bias_sigmas << Vec3::Constant(params_.first_accel_bias_sigma), Vec3::Constant(params_.first_gyro_bias_sigma);
    inc.factors.emplace<PriorBiasFactor>(sym::B(0), bias0_guess, bias_sigmas);
  }
  // The first state has no previous one: a whole correlation time's prior.
  addMotionPriors(0, static_cast<std::int64_t>(std::llround(params_.vertical_speed_correlation_s * 1e9)), inc);
  inc.values.insert(sym::X(0), T_w_b0_guess);
  inc.values.insert(sym::V(0), v_w0_guess);
  inc.values.insert(sym::B(0), bias0_guess);
  inc.key_times_ns = {{sym::X(0), t0_ns}, {sym::V(0), t0_ns}, {sym::B(0), t0_ns}};
  inc.new_state = true;
  inc.state_index = 0;
  inc.t_ns = t0_ns;

  started_ = true;
  last_index_ = 0;
  last_t_ns_ = t0_ns;
  newest_state_t_ns_ = t0_ns;
  while (imu_.size() >= 2 && imu_[1].t_ns <= t0_ns) imu_.pop_front();
  standstill_.dropBefore(t0_ns);
  // Re-plan the warm-up ranges from t0 on (each pass moves one to the back).
  for (std::size_t n = ranges_.size(); n > 0; --n) {
    const Measurement r = ranges_.front();
    ranges_.pop_front();
    if (r.t_ns < t0_ns) {
      ++dropped_ranges_;
    } else {
      planRange(r);
    }
  }
  commitImuOnlyStates();
  return inc;
}

void RangeImuGraphStream::addImu(const ImuSample& s) {
  if (finished_) throw std::logic_error("RangeImuGraphStream::addImu: called after finish()");
  if (have_imu_ && s.t_ns <= newest_imu_t_ns_) {
    throw std::invalid_argument("RangeImuGraphStream::addImu: IMU sample at t_ns=" + ns(s.t_ns) +
                                " is not after the previous one at t_ns=" + ns(newest_imu_t_ns_));
  }
  if (!s.accel_m_s2.allFinite() || !s.gyro_rad_s.allFinite()) {
    throw std::invalid_argument("RangeImuGraphStream::addImu: IMU sample at t_ns=" + ns(s.t_ns) + " is not finite");
  }
  // Bounds commitImuOnlyStates' loop (none when waiting forever for ranges).
  if (started_ && options_.max_range_wait_ns != RangeImuStreamOptions::kWaitForever &&
      s.t_ns - newest_state_t_ns_ > options_.max_range_wait_ns + options_.max_gap_ns) {
    throw std::invalid_argument("RangeImuGraphStream::addImu: IMU sample at t_ns=" + ns(s.t_ns) + " is " +
                                ns(s.t_ns - newest_state_t_ns_) + " ns past the newest state (max_range_wait_ns + max_gap_ns " +
                                ns(options_.max_range_wait_ns + options_.max_gap_ns) + ")");
  }
  imu_.push_back(s);
  if (params_.zero_velocity_sigma_m_s > 0.0) standstill_.add(s);
  have_imu_ = true;
  newest_imu_t_ns_ = s.t_ns;
  if (!started_) return;
  // Only after start(t0) with IMU still before t0: keep just the sample in effect.
  while (imu_.size() >= 2 && imu_[1].t_ns <= last_t_ns_) imu_.pop_front();
  commitImuOnlyStates();
}

void RangeImuGraphStream::addMeasurement(const Measurement& r) {
  const std::string where =
      std::string("RangeImuGraphStream::addMeasurement: ") + toString(r.kind) + " at t_ns=" + ns(r.t_ns);
  if (finished_) throw std::logic_error("RangeImuGraphStream::addMeasurement: called after finish()");
  const bool ultrasonic = r.kind == Measurement::Kind::kUltrasonic;
  const std::size_t known = ultrasonic ? params_.p_w_ultrasonic.size() : p_w_anchors_.size();
  auto check_anchor = [&](std::uint32_t id) {
    if (id >= known) {
      throw std::invalid_argument(where + " names unknown " + (ultrasonic ? "ultrasonic beacon " : "anchor ") +
                                  std::to_string(id) + " (" + std::to_string(known) + " known)");
    }
  };
  check_anchor(r.anchor);
  if (r.kind == Measurement::Kind::kTdoa) {
    check_anchor(r.anchor_b);
    if (r.anchor_b == r.anchor) throw std::invalid_argument(where + ": anchor_b equals anchor_a");
  }
  if (!std::isfinite(r.value_m)) throw std::invalid_argument(where + ": the value is not finite");
  if (have_range_ && r.t_ns < newest_range_t_ns_) {
    throw std::invalid_argument(where + " is before the previous measurement at t_ns=" + ns(newest_range_t_ns_));
  }
  if (started_ && r.t_ns < newest_state_t_ns_) {
    throw std::invalid_argument(where + " is before the newest state at t_ns=" + ns(newest_state_t_ns_) +
                                " (the start, or an IMU-only state committed after max_range_wait_ns)");
  }
  if (started_ && r.t_ns - newest_state_t_ns_ > options_.max_gap_ns) {
    throw std::invalid_argument(where + " is " + ns(r.t_ns - newest_state_t_ns_) +
                                " ns past the newest state (max_gap_ns " + ns(options_.max_gap_ns) + ")");
  }
  have_range_ = true;
  newest_range_t_ns_ = r.t_ns;
  if (r.kind == Measurement::Kind::kRange) range_repeats_.add(r.anchor, r.tag, r.t_ns);
  if (started_) {
    planRange(r);
  } else {
    ranges_.push_back(r);
  }
}

void RangeImuGraphStream::finish() {
  if (!started_) throw std::logic_error("RangeImuGraphStream::finish: call start() first");
  finished_ = true;
}

void RangeImuGraphStream::planRange(const Measurement& r) {
  ranges_.push_back(r);
  const std::int64_t gap_ns = r.t_ns - newest_state_t_ns_;
  if (gap_ns <= params_.same_state_window_ns) {
    // Joins the newest state's group; if that state is already out, it rides along later.
    if (plan_.empty()) {
      ++carry_ranges_;
    } else {
      ++plan_.back().n_ranges;
    }
    return;
  }
  const std::int64_t max_ns = params_.max_state_interval_ns;
  const std::int64_t pieces = gap_ns / max_ns + (gap_ns % max_ns != 0 ? 1 : 0);
  for (std::int64_t j = 1; j < pieces; ++j) plan_.push_back({gapStateTime(newest_state_t_ns_, gap_ns, j, pieces), 0});
  plan_.push_back({r.t_ns, 1});
  newest_state_t_ns_ = r.t_ns;
}

void RangeImuGraphStream::commitImuOnlyStates() {
  if (!have_imu_ || options_.max_range_wait_ns == RangeImuStreamOptions::kWaitForever) return;
  while (newest_imu_t_ns_ - newest_state_t_ns_ > options_.max_range_wait_ns) {
    newest_state_t_ns_ += params_.max_state_interval_ns;
    plan_.push_back({newest_state_t_ns_, 0});
  }
}

bool RangeImuGraphStream::stateReady(const PlannedState& s) const {
  const bool imu_covers = have_imu_ && newest_imu_t_ns_ >= s.t_ns;
  const bool group_closed =
      plan_.size() > 1 || finished_ || newest_imu_t_ns_ - s.t_ns > params_.same_state_window_ns;
  return imu_covers && group_closed;
}

bool RangeImuGraphStream::carryClosed() const {
  return !plan_.empty() || finished_ || (have_imu_ && newest_imu_t_ns_ - last_t_ns_ > params_.same_state_window_ns);
}

std::optional<GraphIncrement> RangeImuGraphStream::next(const StateEstimate& previous) {
  if (!started_) throw std::logic_error("RangeImuGraphStream::next: call start() first");
  if (previous.index != last_index_ || previous.t_ns != last_t_ns_) {
    throw std::invalid_argument("RangeImuGraphStream::next: previous must be the last emitted state (index " +
                                std::to_string(last_index_) + ", t_ns=" + ns(last_t_ns_) + "), got index " +
                                std::to_string(previous.index) + ", t_ns=" + ns(previous.t_ns));
  }
  if (!allFinite(previous.T_w_b) || !previous.v_w.allFinite() || !previous.bias.vector().allFinite()) {
    throw std::invalid_argument("RangeImuGraphStream::next: previous estimate is not finite");
  }
  noise_.notePostFit(previous.index, previous.T_w_b, previous.v_w);  // no-op unless its measurements await it
  if (options_.learn_carry_height) {
    carry_height_.notePostFit(previous.index, previous.t_ns, previous.T_w_b.transformFrom(params_.p_b_tag).z());
  }
  if (!plan_.empty() && stateReady(plan_.front())) return emitState(previous);
  if (carry_ranges_ > 0 && carryClosed()) return emitCarriedRanges();
  return std::nullopt;
}

GraphIncrement RangeImuGraphStream::emitState(const StateEstimate& previous) {
  const PlannedState s = plan_.front();
  const std::uint64_t i = last_index_ + 1;

  pim_.reset(previous.bias);
  std::size_t cursor = 0;
  integrateInterval(imu_, cursor, last_t_ns_, s.t_ns, pim_);

  GraphIncrement inc;
  inc.new_state = true;
  inc.state_index = i;
  inc.t_ns = s.t_ns;
  inc.factors.emplace<CombinedImuFactor>(sym::X(i - 1), sym::V(i - 1), sym::B(i - 1), sym::X(i), sym::V(i),
                                         sym::B(i), pim_);
  addRangeFactors(0, carry_ranges_, i - 1, last_t_ns_, inc);
  addRangeFactors(carry_ranges_, s.n_ranges, i, s.t_ns, inc);
  addAnchorPriors(inc);
  addMotionPriors(i, s.t_ns - last_t_ns_, inc);
  addCarryHold(i, s.t_ns - last_t_ns_, inc);
  const bool still = addStandstillPrior(i, last_t_ns_, s.t_ns, previous.v_w, inc);

  const PreintegratedImu::NavState nav = pim_.predict(previous.T_w_b, previous.v_w, previous.bias);
  inc.values.insert(sym::X(i), nav.T_w_b);
  inc.values.insert(sym::V(i), nav.v_w);
  // Mean of the bias process: b_j = Phi b_i (Phi = I for a random walk).
  inc.values.insert(sym::B(i), ImuBias(Vec6(params_.imu.biasTransition(pim_.dt()).cwiseProduct(previous.bias.vector()))));
  inc.key_times_ns = {{sym::X(i), s.t_ns}, {sym::V(i), s.t_ns}, {sym::B(i), s.t_ns}};

  // Commit (nothing above changed the stream).
  for (std::size_t k = carry_ranges_; k < carry_ranges_ + s.n_ranges; ++k) {
    noise_.notePrediction(i, s.t_ns, ranges_[k], nav.T_w_b, nav.v_w);
    noteHeightEvidence(i, ranges_[k]);
  }
  commitAnchors(inc);
  ranges_.pop_front(carry_ranges_ + s.n_ranges);
  carry_ranges_ = 0;
  plan_.pop_front();
  imu_.pop_front(cursor);  // keep the sample in effect at the new state
  standstill_.dropBefore(s.t_ns);
  standstill_states_ += still;
  last_index_ = i;
  last_t_ns_ = s.t_ns;
  return inc;
}

GraphIncrement RangeImuGraphStream::emitCarriedRanges() {
  GraphIncrement inc;
  inc.new_state = false;
  inc.state_index = last_index_;
  inc.t_ns = last_t_ns_;
  addRangeFactors(0, carry_ranges_, last_index_, last_t_ns_, inc);
  addAnchorPriors(inc);
  commitAnchors(inc);
  ranges_.pop_front(carry_ranges_);
  carry_ranges_ = 0;
  return inc;
}

const char* toString(Measurement::Kind kind) {
  switch (kind) {
    case Measurement::Kind::kRange: return "range";
    case Measurement::Kind::kTdoa: return "tdoa";
    case Measurement::Kind::kUltrasonic: return "ultrasonic";
  }
  return "?";
}

}  // namespace rilo
