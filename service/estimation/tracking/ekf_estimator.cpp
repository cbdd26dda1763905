#include "estimation/tracking/ekf_estimator.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace rilo {
namespace {

EkfParams withImu(EkfParams p, const ImuParams& imu) {
  p.imu = imu;
  return p;
}

/// The EKF does not learn the TDoA packets' excess (measurement_noise.h):
/// fed with its innovations it took the 15 TDoA sims from 0.365 to 0.398 m.
RangeImuGraphParams withoutGapExcess(RangeImuGraphParams graph) {
  graph.tdoa_gap_excess.enabled = false;
  return graph;
}

}  // namespace

EkfEstimator::EkfEstimator(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph, const EkfParams& ekf)
    : p_w_anchors_(std::move(p_w_anchors)),
      graph_(graph),
      ekf_(withImu(ekf, graph.imu)),
      range_model_(graph.range_loss, graph.range_noise),
      tdoa_model_(tdoaModelParams(graph), graph.range_noise),
      ultrasonic_loss_(makeRangeLoss(graph.ultrasonic_loss, withSigma(graph.range_noise, graph.ultrasonic_sigma_m))),
      noise_(p_w_anchors_, withoutGapExcess(graph_), ekf.dynamic_covariance),
      standstill_(graph.standstill) {
  if (graph_.same_state_window_ns < 0) throw std::invalid_argument("EkfEstimator: same_state_window_ns must be >= 0");
  if (!(graph_.zero_velocity_sigma_m_s >= 0.0 && std::isfinite(graph_.zero_velocity_sigma_m_s))) {
    throw std::invalid_argument("EkfEstimator: zero_velocity_sigma_m_s must be finite and >= 0");
  }
  if (!(graph_.vertical_speed_correlation_s > 0.0 && std::isfinite(graph_.vertical_speed_correlation_s))) {
    throw std::invalid_argument("EkfEstimator: vertical_speed_correlation_s must be finite and > 0");
  }
  pending_.reserve(64);
  ready_.reserve(16);
}

UpdateStats EkfEstimator::start(std::int64_t t0_ns, const Pose3& T_w_b0, const Vec3& v_w0, const ImuBias& bias0,
                                const std::optional<StartCovariance>& covariance) {
  Mat15 P = Mat15::Zero();
  if (covariance) {
    // Error [dtheta body, dp world, dv, dba, dbg]; Pose3's translation
    // perturbation is body-frame (p + R rho), so dp = R rho.
    const StartCovariance& c = *covariance;
    const Mat3& R = T_w_b0.R;
    P.block<3, 3>(0, 0) = c.pose.topLeftCorner<3, 3>();
    P.block<3, 3>(0, 3) = c.pose.topRightCorner<3, 3>() * R.transpose();
    P.block<3, 3>(3, 0) = P.block<3, 3>(0, 3).transpose();
    P.block<3, 3>(3, 3) = R * c.pose.bottomRightCorner<3, 3>() * R.transpose();
    P.block<3, 3>(6, 6) = c.velocity;
    P.block<6, 6>(9, 9) = c.bias;  // ErrorStateEkf::initialize checks P (finite, symmetric, positive definite)
  } else {
    // The graph's first-state priors: rotation sigmas in the body chart, an
    // isotropic position sigma (the same in world), velocity and biases.
    P.block<3, 3>(0, 0).diagonal() = graph_.first_pose_sigmas.head<3>().cwiseAbs2();
    P.block<3, 3>(3, 3).diagonal().setConstant(graph_.first_pose_sigmas.tail<3>().cwiseAbs2().maxCoeff());
    P.block<3, 3>(6, 6).diagonal().setConstant(graph_.first_velocity_sigma_m_s * graph_.first_velocity_sigma_m_s);
    P.block<3, 3>(9, 9).diagonal().setConstant(graph_.first_accel_bias_sigma * graph_.first_accel_bias_sigma);
    P.block<3, 3>(12, 12).diagonal().setConstant(graph_.first_gyro_bias_sigma * graph_.first_gyro_bias_sigma);
  }
  EkfState x;
  x.R_w_b = T_w_b0.R;
  x.p_w_b = T_w_b0.p;
  x.v_w = v_w0;
  x.bias = bias0;
  ekf_.initialize(t0_ns, x, P);
  last_group_t0_ns_ = t0_ns;
  groups_opened_ = 0;
  standstill_.dropBefore(t0_ns);
  latest_ = ekf_.estimate();
  filtered_.push_back({t0_ns, latest_.T_w_b});
  return UpdateStats();
}

void EkfEstimator::addImu(const ImuSample& sample) {
  if (!started()) throw std::logic_error("EkfEstimator::addImu: call start() first");
  if (graph_.zero_velocity_sigma_m_s > 0.0) standstill_.add(sample);
  drainPending(&sample, false);
  if (group_open_ && sample.t_ns - group_t0_ns_ > graph_.same_state_window_ns) closeGroup();
  if (sample.t_ns > ekf_.t_ns() || !have_imu_) ekf_.propagate(sample);
  last_imu_ = sample;
  have_imu_ = true;
}

void EkfEstimator::addMeasurement(const Measurement& m) {
  if (!started()) throw std::logic_error("EkfEstimator::addMeasurement: call start() first");
  if (m.t_ns < ekf_.t_ns() - graph_.same_state_window_ns) return;  // before the start: nothing to update
  pending_.push_back(m);
}

void EkfEstimator::finish() {
  drainPending(nullptr, true);
  if (group_open_) closeGroup();
}

void EkfEstimator::drainPending(const ImuSample* next, bool all) {
  while (pending_head_ < pending_.size()) {
    const Measurement& m = pending_[pending_head_];
    if (!all && (next == nullptr || m.t_ns > next->t_ns)) break;
    if (group_open_ && m.t_ns - group_t0_ns_ > graph_.same_state_window_ns) closeGroup();
    if (next != nullptr && m.t_ns > ekf_.t_ns()) propagateTo(m.t_ns, *next);
    apply(m);
    ++pending_head_;
  }
  if (pending_head_ == pending_.size()) {
    pending_.clear();
    pending_head_ = 0;
  }
}

void EkfEstimator::propagateTo(std::int64_t t_ns, const ImuSample& next) {
  if (!have_imu_ || next.t_ns <= last_imu_.t_ns) return;
  const double a = static_cast<double>(t_ns - last_imu_.t_ns) / static_cast<double>(next.t_ns - last_imu_.t_ns);
  ImuSample mid;
  mid.t_ns = t_ns;
  mid.gyro_rad_s = last_imu_.gyro_rad_s + a * (next.gyro_rad_s - last_imu_.gyro_rad_s);
  mid.accel_m_s2 = last_imu_.accel_m_s2 + a * (next.accel_m_s2 - last_imu_.accel_m_s2);
  ekf_.propagate(mid);
  last_imu_ = mid;
}

void EkfEstimator::apply(const Measurement& m) {
  const auto t0 = std::chrono::steady_clock::now();
  EkfUpdateResult r;
  // The kind's configured sigma unless dynamic covariance is on (and for TDoA
  // rows the receiver vouches for as LOS even then: tdoa_model.h).
  const double sigma_m = tdoa_model_.vouchedLos(m) ? noise_.nominalSigma(m.kind) : noise_.sigma(m);
  switch (m.kind) {
    case Measurement::Kind::kRange: {
      if (m.anchor >= p_w_anchors_.size()) return;
      // The graph's range model: a range the receiver flags as NLOS gets the NLOS component.
      const RangeTerm t = range_model_.term(m, sigma_m);
      r = ekf_.updateRange(p_w_anchors_[m.anchor], graph_.leverArm(m.tag), t.range_m, t.sigma_m, t.loss.get());
      break;
    }
    case Measurement::Kind::kTdoa:
      if (m.anchor >= p_w_anchors_.size() || m.anchor_b >= p_w_anchors_.size() || m.anchor == m.anchor_b) return;
      if (ekf_.params().tdoa_group_update) {
        if (!group_open_) openGroup(m.t_ns);
        if (tdoa_n_ == kEkfMaxGroupRows) flushTdoaGroup();
        tdoa_rows_[tdoa_n_] = {p_w_anchors_[m.anchor], p_w_anchors_[m.anchor_b], m.anchor, m.anchor_b, m.value_m,
                               tdoa_model_.symmetricSigma(m, sigma_m)};
        tdoa_meas_[tdoa_n_++] = m;
        ++group_size_;
        group_time_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return;
      }
      r = ekf_.updateTdoa(p_w_anchors_[m.anchor], p_w_anchors_[m.anchor_b], graph_.p_b_tag, m.value_m,
                          tdoa_model_.symmetricSigma(m, sigma_m), tdoa_model_.loss().get());
      break;
    case Measurement::Kind::kUltrasonic:
      if (m.anchor >= graph_.p_w_ultrasonic.size()) return;
      r = ekf_.updateUltrasonic(graph_.p_w_ultrasonic[m.anchor], graph_.p_b_ultrasonic, m.value_m, sigma_m,
                                std::nullopt, ultrasonic_loss_.get());
      break;
  }
  noise_.noteInnovation(m, r.innovation, r.predicted_variance_m2);
  if (!group_open_) openGroup(m.t_ns);
  applyHeightBand();
  ++group_size_;
  group_accepted_ += r.status == UpdateStatus::kAccepted;
  group_time_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  group_state_ = ekf_.estimate();
}

void EkfEstimator::openGroup(std::int64_t t_ns) {
  group_open_ = true;
  group_t0_ns_ = t_ns;
  group_size_ = group_accepted_ = 0;
  group_time_s_ = 0.0;
  // One group is one state of the graph, which gets the vertical speed
  // prior once (verticalSpeedPriorSigma over the interval since the previous
  // group; the first group, like the graph's first state, a whole
  // correlation time's): the same motion knowledge for the baseline.
  if (graph_.vertical_speed_sigma_m_s > 0.0) {
    const std::int64_t tau_ns = static_cast<std::int64_t>(std::llround(graph_.vertical_speed_correlation_s * 1e9));
    const std::int64_t interval_ns = groups_opened_ == 0 ? tau_ns : t_ns - last_group_t0_ns_;
    ekf_.applyVerticalSpeedPrior(verticalSpeedPriorSigma(graph_, interval_ns));
  }
  ++groups_opened_;
  applyStandstill(t_ns);
  group_state_ = ekf_.estimate();
}

void EkfEstimator::applyStandstill(std::int64_t t_ns) {
  // As RangeImuGraphStream::addStandstillPrior on the state this group is:
  // the interval since the previous group still, the same sigma.
  const std::int64_t t_prev_ns = last_group_t0_ns_;
  last_group_t0_ns_ = t_ns;
  if (graph_.zero_velocity_sigma_m_s <= 0.0) return;
  const bool still = standstill_.stillFor(t_prev_ns, t_ns, ekf_.state().v_w);
  standstill_.dropBefore(t_ns);
  if (!still) return;
  ekf_.applyZeroVelocityPrior(standstillPriorSigma(graph_.zero_velocity_sigma_m_s, t_ns - t_prev_ns));
}

void EkfEstimator::applyHeightBand() {
  // The graph holds every state in the tag height band (HeightBandFactor on
  // the body height); the filter applies the same band after each update.
  // Without it, NLOS-long ranges from anchors above pulled the filtered
  // height 2 m down within 10 s and the filter diverged.
  const HeightBand& band = graph_.height_band;
  if (band.enabled) ekf_.applyHeightBand(band.minZ() - graph_.p_b_tag.z(), band.maxZ() - graph_.p_b_tag.z(), band.sigma_m);
}

void EkfEstimator::flushTdoaGroup() {
  if (tdoa_n_ == 0) return;
  const auto t0 = std::chrono::steady_clock::now();
  const EkfGroupResult r = ekf_.updateTdoaGroup(tdoa_rows_, tdoa_n_, graph_.p_b_tag, tdoa_model_.loss().get());
  for (int i = 0; i < tdoa_n_; ++i) {
    noise_.noteInnovation(tdoa_meas_[i], r.innovation[i], r.predicted_variance_m2[i]);
  }
  tdoa_n_ = 0;
  applyHeightBand();
  // Rows the gate refused count as refused for the tracking-failure share even
  // when gate recovery applied them: recovery must not hide a lost filter.
  group_accepted_ += r.accepted - r.recovered;
  group_time_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  group_state_ = ekf_.estimate();
}

void EkfEstimator::closeGroup() {
  flushTdoaGroup();
  group_open_ = false;
  latest_ = group_state_;
  latest_.index = ++updates_;
  filtered_.push_back({latest_.t_ns, latest_.T_w_b});
  UpdateStats s;
  s.factors_added = group_size_;
  s.variables_total = 1;
  s.step_tries = 1;
  // Lock lost: the filter gates most of what it hears. A filter whose state
  // drifted off rejects nearly every measurement from then on and never comes
  // back (seen on the hall sim with TDoA: 90 % gated while the error grew to
  // 50 m); reported as a rejected step, so that a long enough run of them
  // makes the Localizer re-initialize (max_consecutive_rejections; a lucky
  // measurement now and then breaks such a run, hence also the windowed
  // share, LocalizerParams::rejection_window). Healthy tracking gates
  // 15-35 % of the rows there, so few groups lose half of theirs.
  // Rows gate recovery applied (ErrorStateEkf::updateTdoaGroup) count as
  // refused here, see flushTdoaGroup().
  s.step_accepted = 2 * group_accepted_ >= group_size_;
  s.time_s = group_time_s_;
  ready_.push_back(s);
}

int EkfEstimator::process(std::vector<UpdateStats>* stats) {
  const int n = static_cast<int>(ready_.size());
  if (stats) stats->insert(stats->end(), ready_.begin(), ready_.end());
  ready_.clear();
  return n;
}

void EkfEstimator::drainSmoothed(std::vector<TimedPose>& out, bool all) {
  (void)all;  // a filter holds nothing back
  out.insert(out.end(), filtered_.begin(), filtered_.end());
  filtered_.clear();
}

std::optional<CovarianceBlock> EkfEstimator::latestPoseCovariance() {
  if (!started()) return std::nullopt;
  return CovarianceBlock(ekf_.poseCovarianceInRetractionChart());
}

std::optional<CovarianceBlock> EkfEstimator::latestVelocityCovariance() {
  if (!started()) return std::nullopt;
  return CovarianceBlock(ekf_.covariance().block<3, 3>(6, 6));
}

}  // namespace rilo
