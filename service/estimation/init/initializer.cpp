#include "estimation/init/initializer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/factors/tdoa_factor.h"
#include "estimation/init/format.h"
#include "estimation/init/window_time.h"
#include "estimation/noise/noise_model_factory.h"
#include "estimation/solver/batch_lm.h"

namespace rilo {

using init_detail::imuIndexAt;
using init_detail::rangeIndexFrom;
using init_detail::strprintf;
using init_detail::toNs;
using init_detail::toS;

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
/// Fix starts a window tries, fix_window_s apart from its first measurement (step 1 of alignWindow).
constexpr int kFixStarts = 4;

/// TdoaFix as the alignment's starting point (no velocity: the TDoA fix is a position).
TagFix tagFixOf(const TdoaFix& f) {
  TagFix t;
  t.valid = f.valid;
  t.message = "TDoA fix: " + f.message;
  t.t_ns = f.t_ns;
  t.p_w_tag = f.p_w_tag;
  t.anchors_heard = f.anchors_heard + f.beacons_heard;
  t.anchors_used = f.anchors_used;
  t.ranges = f.measurements + f.ultrasonic_ranges;
  t.inliers = f.inliers + f.ultrasonic_inliers;
  t.rms_m = f.rms_m;
  t.pdop = f.pdop;
  t.sigma_p_m = f.sigma_p_m;
  t.cost = f.cost;
  t.second_cost_gap = f.second_cost_gap;
  t.mirror_ambiguous = f.mirror_ambiguous;
  return t;
}

}  // namespace

const char* toString(InitState s) {
  switch (s) {
    case InitState::kWaitingForData: return "waiting for data";
    case InitState::kTooFewAnchors: return "too few anchors";
    case InitState::kPoorFix: return "poor fix";
    case InitState::kNoGravity: return "no gravity";
    case InitState::kYawUnobservable: return "yaw unobservable";
    case InitState::kBatchRejected: return "batch rejected";
    case InitState::kInitialized: return "initialized";
  }
  return "unknown";
}

void InitializerParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("InitializerParams.") + field + " " + rule);
  };
  graph.imu.validate();
  if (!(graph.range_noise.sigma_m > 0.0)) fail("graph.range_noise.sigma_m", "must be > 0");
  if (!(min_window_s > 0.0)) fail("min_window_s", "must be > 0");
  if (!(window_s >= min_window_s)) fail("window_s", "must be >= min_window_s");
  if (!(max_window_s >= window_s)) fail("max_window_s", "must be >= window_s");
  if (min_window_ranges < 0) fail("min_window_ranges", "must be >= 0");
  if (!(provisional_fix_interval_s >= 0.0 && std::isfinite(provisional_fix_interval_s))) {
    fail("provisional_fix_interval_s", "must be finite and >= 0 (0: off)");
  }
  if (!(provisional_fix_window_s > 0.0 && provisional_fix_max_window_s >= provisional_fix_window_s &&
        std::isfinite(provisional_fix_max_window_s))) {
    fail("provisional_fix_window_s", "must be > 0 and at most provisional_fix_max_window_s (finite)");
  }
  if (!(provisional_min_inlier_fraction >= 0.0 && provisional_min_inlier_fraction <= 1.0)) {
    fail("provisional_min_inlier_fraction", "must be in [0, 1]");
  }
  if (min_alignment_ranges < 4) fail("min_alignment_ranges", "must be >= 4");
  if (!(attempt_interval_s > 0.0)) fail("attempt_interval_s", "must be > 0");
  if (!(max_attempt_interval_s >= attempt_interval_s)) fail("max_attempt_interval_s", "must be >= attempt_interval_s");
  if (!(fix_window_s > 0.0)) fail("fix_window_s", "must be > 0");
  if (!(fix_max_window_s >= fix_window_s)) fail("fix_max_window_s", "must be >= fix_window_s");
  if (!(max_alignment_yaw_sigma_rad > 0.0)) fail("max_alignment_yaw_sigma_rad", "must be > 0");
  if (!(min_yaw_cost_gap >= 0.0)) fail("min_yaw_cost_gap", "must be >= 0");
  if (!(max_yaw_gap_noise_scale >= 1.0) || !std::isfinite(max_yaw_gap_noise_scale)) {
    fail("max_yaw_gap_noise_scale", "must be finite and >= 1 (1 disables)");
  }
  if (!(max_alignment_cost_per_range > 0.0)) fail("max_alignment_cost_per_range", "must be > 0");
  if (!(heavy_nlos_after_s >= 0.0)) fail("heavy_nlos_after_s", "must be >= 0 (+inf: off)");
  if (!(max_short_range_share >= 0.0 && max_short_range_share <= 1.0)) fail("max_short_range_share", "must be in [0, 1]");
  if (!(heavy_nlos_cost_factor >= 1.0) || !std::isfinite(heavy_nlos_cost_factor)) {
    fail("heavy_nlos_cost_factor", "must be finite and >= 1 (1 disables)");
  }
  if (!(max_position_sigma_m > 0.0)) fail("max_position_sigma_m", "must be > 0");
  if (!(max_yaw_sigma_rad > 0.0)) fail("max_yaw_sigma_rad", "must be > 0");
  if (!(max_range_cost_per_range > 0.0)) fail("max_range_cost_per_range", "must be > 0");
  if (!(max_outside_anchors_m >= 0.0)) fail("max_outside_anchors_m", "must be >= 0 (+inf: off)");
  if (!(max_imu_cost_per_factor > 0.0)) fail("max_imu_cost_per_factor", "must be > 0");
  if (!(max_range_m > 0.0)) fail("max_range_m", "must be > 0");
  if (!(zero_velocity_sigma_m_s > 0.0)) fail("zero_velocity_sigma_m_s", "must be > 0 (+inf disables)");
  if (!(batch_gate_sigma_factor >= 1.0)) fail("batch_gate_sigma_factor", "must be >= 1 (+inf disables)");
  if (!(batch_gate_max_s > 0.0)) fail("batch_gate_max_s", "must be > 0");
  if (hand_over_later_measurements < 0) fail("hand_over_later_measurements", "must be >= 0 (0: the newest state)");
  if (!(hand_over_sparse_span_s >= 0.0)) fail("hand_over_sparse_span_s", "must be >= 0");
  if (!(max_hand_over_residual_scale >= 1.0) || !std::isfinite(max_hand_over_residual_scale)) {
    fail("max_hand_over_residual_scale", "must be finite and >= 1 (1 disables)");
  }
  hand_over_conditioning.validate();
  height_band.validate("InitializerParams.height_band");
  fix.validate();
  gravity.validate();
  alignment.validate();
  lm.validate();
}

Initializer::Initializer(std::vector<Vec3> p_w_anchors, InitializerParams params)
    : p_w_anchors_(std::move(p_w_anchors)), params_(std::move(params)) {
  if (p_w_anchors_.empty()) throw std::invalid_argument("Initializer: p_w_anchors is empty");
  for (const Vec3& a : p_w_anchors_) {
    if (!a.allFinite()) throw std::invalid_argument("Initializer: p_w_anchors has a non-finite anchor");
  }
  // Shared settings come from the graph parameters.
  const RangeImuGraphParams& g = params_.graph;
  const RobustLossPtr asym = makeRangeLoss("asymmetric", g.range_noise);  // validates the noise params
  params_.fix.sigma_m = g.range_noise.sigma_m;
  params_.fix.long_side_loss = asym;
  params_.fix.band = params_.height_band;
  params_.alignment.range_sigma_m = g.range_noise.sigma_m;
  params_.alignment.long_side_loss = asym;
  params_.alignment.p_b_tag = g.p_b_tag;
  params_.alignment.tag_lever_arms = g.tag_lever_arms;
  params_.alignment.gravity_m_s2 = g.imu.gravity_m_s2;
  params_.alignment.accel_bias_sigma = g.first_accel_bias_sigma;
  params_.alignment.gyro_bias_sigma = g.first_gyro_bias_sigma;
  params_.alignment.band = params_.height_band;
  params_.alignment.tdoa_sigma_m = g.tdoa_sigma_m;
  params_.alignment.p_b_ultrasonic = g.p_b_ultrasonic;
  params_.alignment.p_w_ultrasonic = g.p_w_ultrasonic;
  params_.tdoa_fix.sigma_m = g.tdoa_sigma_m;
  params_.tdoa_fix.ultrasonic_sigma_m = g.ultrasonic_sigma_m;
  params_.tdoa_fix.ultrasonic_offset_m = (g.p_b_ultrasonic - g.p_b_tag).norm();
  params_.tdoa_fix.band = params_.height_band;
  if (params_.batch_flagged_mixture) params_.graph.range_noise.flagged_nlos_component = false;
  params_.validate();
  p_w_fix_sources_ = p_w_anchors_;
  p_w_fix_sources_.insert(p_w_fix_sources_.end(), g.p_w_ultrasonic.begin(), g.p_w_ultrasonic.end());
  interval_s_ = params_.attempt_interval_s;
}

void Initializer::setStatus(InitState s, std::string message) {
  status_.state = s;
  status_.message = std::move(message);
}

void Initializer::reset() {
  imu_.clear();
  meas_.clear();
  have_data_ = false;
  data_start_ns_ = 0;
  first_range_ns_.reset();
  last_attempt_ns_ = 0;
  attempted_ = false;
  interval_s_ = params_.attempt_interval_s;
  grow_window_ = false;
  no_fix_before_ns_.reset();
  trimmed_before_ns_.reset();
  dropped_imu_ = dropped_meas_ = 0;
  status_ = InitStatus();
  batch_stage_reached_ = false;
  last_batch_ns_ = 0;
  rejected_input_.reset();
  result_.reset();
  provisional_.reset();
  provisional_tried_ns_.reset();
}

void Initializer::addImu(const ImuSample& s) {
  if (!s.accel_m_s2.allFinite() || !s.gyro_rad_s.allFinite() || (!imu_.empty() && s.t_ns <= imu_.back().t_ns)) {
    ++dropped_imu_;
    return;
  }
  if (!have_data_) {
    have_data_ = true;
    data_start_ns_ = s.t_ns;
  }
  imu_.push_back(s);
  trim();
}

void Initializer::addMeasurement(const Measurement& m) {
  const std::size_t sources =
      m.kind == Measurement::Kind::kUltrasonic ? params_.graph.p_w_ultrasonic.size() : p_w_anchors_.size();
  const bool tdoa = m.kind == Measurement::Kind::kTdoa;
  const bool known = m.anchor < sources && (!tdoa || (m.anchor_b < sources && m.anchor_b != m.anchor));
  const bool plausible = std::isfinite(m.value_m) && std::abs(m.value_m) <= params_.max_range_m && (tdoa || m.value_m >= 0.0);
  if (!known || !plausible || (!meas_.empty() && m.t_ns < meas_.back().t_ns)) {
    ++dropped_meas_;
    return;
  }
  if (!have_data_) {
    have_data_ = true;
    data_start_ns_ = m.t_ns;
  }
  if (m.kind == Measurement::Kind::kRange && !first_range_ns_) first_range_ns_ = m.t_ns;
  meas_.push_back(m);
}

void Initializer::trim() {
  // Keep max_window_s (plus the fix window, so the oldest window start still
  // has its fix) behind the newest IMU sample; erase in chunks of >= 2 s.
  if (imu_.empty()) return;
  std::int64_t keep_from = imu_.back().t_ns - toNs(params_.max_window_s + params_.fix_max_window_s + 1.0);
  if (result_) keep_from = std::min(keep_from, result_->state.t_ns);
  if (imu_.front().t_ns + toNs(2.0) > keep_from) return;
  const std::size_t i = imuIndexAt(imu_, keep_from);  // keep the sample in effect at keep_from
  imu_.erase(imu_.begin(), imu_.begin() + static_cast<std::ptrdiff_t>(i));
  const std::size_t k = rangeIndexFrom(meas_, keep_from);
  meas_.erase(meas_.begin(), meas_.begin() + static_cast<std::ptrdiff_t>(k));
  trimmed_before_ns_ = keep_from;
}

const InitResult& Initializer::result() const {
  if (!result_) throw std::logic_error("Initializer::result: not initialized (" + status_.message + ")");
  return *result_;
}

bool Initializer::process() {
  if (initialized()) return true;
  return attemptDue() && attempt();
}

bool Initializer::attemptDue() {
  if (initialized()) return false;
  updateProvisionalFix();
  if (imu_.empty()) {
    setStatus(InitState::kWaitingForData, meas_.empty() ? "waiting: no samples" : "waiting: no IMU samples (ranges only)");
    return false;
  }
  const std::int64_t t_now = imu_.back().t_ns;
  const double span_s = toS(t_now - data_start_ns_);
  if (span_s < params_.min_window_s) {
    setStatus(InitState::kWaitingForData,
              strprintf("waiting: %.1f s of data, need %.1f s", std::max(0.0, span_s), params_.min_window_s));
    return false;
  }
  return !attempted_ || t_now - last_attempt_ns_ >= toNs(interval_s_);
}

void Initializer::setCancelFlag(const std::atomic<bool>* cancel) {
  cancel_ = cancel;
  params_.lm.cancel = cancel;
}

void Initializer::adoptAttempt(Initializer&& attempted) {
  status_ = std::move(attempted.status_);
  result_ = std::move(attempted.result_);
  attempted_ = attempted.attempted_;
  last_attempt_ns_ = attempted.last_attempt_ns_;
  interval_s_ = attempted.interval_s_;
  grow_window_ = attempted.grow_window_;
  no_fix_before_ns_ = attempted.no_fix_before_ns_;
  rejected_input_ = attempted.rejected_input_;
  batch_stage_reached_ = attempted.batch_stage_reached_;
  last_batch_ns_ = attempted.last_batch_ns_;
  // The hand-over replays the IMU sample in effect at the state and every measurement from it on.
  if (result_ && (imu_.empty() || result_->state.t_ns < imu_.front().t_ns ||
                  (trimmed_before_ns_ && result_->state.t_ns < *trimmed_before_ns_))) {
    setStatus(InitState::kBatchRejected,
              strprintf("the attempt's result came %.1f s of data late: its hand-over state is no longer buffered",
                        imu_.empty() ? 0.0 : toS(imu_.back().t_ns - result_->state.t_ns)));
    result_.reset();
  }
}

bool Initializer::attempt() {
  if (initialized()) return true;
  ++status_.attempts;
  attempted_ = true;
  last_attempt_ns_ = imu_.empty() ? 0 : imu_.back().t_ns;
  status_.t_ns = last_attempt_ns_;
  try {
    const bool ok = runAttempt();
    if (!ok && cancelled()) {
      // Not the data's verdict: the same data may be tried again, at the usual interval.
      setStatus(InitState::kBatchRejected, "attempt stopped unfinished (over its time budget)");
      rejected_input_.reset();
      result_.reset();
      return false;
    }
    if (!ok && (status_.state == InitState::kYawUnobservable || status_.state == InitState::kBatchRejected)) {
      interval_s_ = std::min(params_.max_attempt_interval_s, 1.5 * interval_s_);
    }
    return ok;
  } catch (const std::exception& e) {
    // A data problem that slipped through a solver's checks: report, never throw.
    setStatus(InitState::kBatchRejected, std::string("attempt failed: ") + e.what());
    return false;
  }
}

bool Initializer::runAttempt() {
  const InitializerParams& P = params_;
  if (imu_.empty()) {
    setStatus(InitState::kWaitingForData, meas_.empty() ? "waiting: no samples" : "waiting: no IMU samples (ranges only)");
    return false;
  }
  if (meas_.empty()) {
    setStatus(InitState::kWaitingForData, "waiting: no ranges (IMU only)");
    return false;
  }
  const std::int64_t t_now = imu_.back().t_ns;
  // The batch was rejected (solved or gated) on exactly this data: the same
  // attempt would reach the same verdict. Keep it instead of repeating it.
  const InputStamp stamp{t_now, meas_.size(), meas_.back().t_ns};
  if (rejected_input_ && *rejected_input_ == stamp && status_.state == InitState::kBatchRejected) return false;
  rejected_input_.reset();
  const std::int64_t span = t_now - std::max(imu_.front().t_ns, data_start_ns_);
  const std::size_t end = rangeIndexFrom(meas_, t_now + 1);  // measurements the IMU covers

  // The Ranging-IMU Fusion paper's window (shorter at first), grown for sparse ranging until it
  // holds min_window_ranges; up to max_window_s once it proved too short for yaw.
  const std::int64_t W_max = std::min(toNs(P.max_window_s), span);
  std::int64_t W = std::min(toNs(P.window_s), span);
  if (P.min_window_ranges > 0) {
    if (end >= static_cast<std::size_t>(P.min_window_ranges)) {
      W = std::max(W, std::min(W_max, t_now - meas_[end - static_cast<std::size_t>(P.min_window_ranges)].t_ns));
    } else {
      W = W_max;
    }
  }
  AlignedWindow aligned;
  if (!grow_window_ || W >= W_max) {
    aligned = alignWindow(W, t_now, end, P.fix_max_window_s);
    if (cancelled()) return false;
    if (!aligned.ok && aligned.state == InitState::kYawUnobservable && W >= toNs(P.window_s) && W < toNs(P.max_window_s)) {
      grow_window_ = true;  // the motion is too gentle for this window: take longer ones from now on
    }
  }
  if (grow_window_ && !aligned.ok && W < W_max) {
    // The longest window that does not start where the fix is known to fail.
    // Without this a grown window stayed pinned to the data's first seconds
    // while they gave no fix (office TDoA sim, seed 7: 4 of 6 anchors NLOS
    // there), and the start waited 68 s for the window to slide past them.
    // Once a start failed, a later one needs a fix from its own first
    // seconds, no longer than the data's rate needs for one (twice the
    // count, at least fix_window_s): a fix window grown far into the good
    // seconds dates their fix back into the bad ones, and the batch then
    // holds seconds that only two anchors or NLOS paths saw (a 2-anchor
    // start at 40 Hz: yaw 23 deg off at a claimed 3.3). Capped at
    // fix_window_s alone, 4 Hz ranging never had enough for a fix after
    // one failure and kept the Ranging-IMU Fusion paper's window for good.
    double short_fix_s = P.fix_max_window_s;
    if (end >= 2 && meas_[end - 1].t_ns > meas_.front().t_ns) {
      const double rate_hz = static_cast<double>(end - 1) / toS(meas_[end - 1].t_ns - meas_.front().t_ns);
      const int count = std::max(P.fix.min_ranges, P.tdoa_fix.min_measurements);
      short_fix_s = std::clamp(2.0 * count / rate_hz, P.fix_window_s, P.fix_max_window_s);
    }
    const std::int64_t step_ns = std::max<std::int64_t>(1, toNs(kFixStarts * P.fix_window_s));
    std::int64_t Wg = no_fix_before_ns_ ? std::min(W_max, t_now - *no_fix_before_ns_) : W_max;
    for (;;) {
      Wg = std::max(Wg, W);
      const bool after_failure = no_fix_before_ns_ && *no_fix_before_ns_ > t_now - W_max;
      aligned = alignWindow(Wg, t_now, end, after_failure && Wg > W ? short_fix_s : P.fix_max_window_s);
      if (aligned.ok || !aligned.fix_failed || Wg == W || cancelled()) break;
      no_fix_before_ns_ = meas_[aligned.begin].t_ns + step_ns;
      Wg = t_now - *no_fix_before_ns_;
    }
    if (!aligned.ok) aligned.message += strprintf(" (window %.1f s)", toS(Wg));
  }
  if (cancelled()) return false;
  if (!aligned.ok) {
    setStatus(aligned.state, aligned.message);
    return false;
  }
  const bool ok = solveBatch(aligned, t_now);
  if (!ok && status_.state == InitState::kBatchRejected) rejected_input_ = stamp;
  return ok;
}

// Enough for a fix: by multilateration's counts when there are two-way
// ranges, else by the TDoA fix's.
bool Initializer::enoughForFix(std::size_t f0, std::size_t f1) const {
  const bool ranges = std::any_of(meas_.begin() + static_cast<std::ptrdiff_t>(f0), meas_.begin() + static_cast<std::ptrdiff_t>(f1),
                                  [](const Measurement& m) { return m.kind == Measurement::Kind::kRange; });
  const int anchors = ranges ? params_.fix.min_anchors : params_.tdoa_fix.min_anchors;
  const int count = ranges ? params_.fix.min_ranges : params_.tdoa_fix.min_measurements;
  return sourcesHeard(f0, f1) >= anchors && static_cast<int>(f1 - f0) >= count;
}

int Initializer::sourcesHeard(std::size_t begin, std::size_t end) const {
  std::set<std::uint32_t> anchors, beacons;
  for (std::size_t k = begin; k < end; ++k) {
    const Measurement& m = meas_[k];
    if (m.kind == Measurement::Kind::kUltrasonic) {
      beacons.insert(m.anchor);
      continue;
    }
    anchors.insert(m.anchor);
    if (m.kind == Measurement::Kind::kTdoa) anchors.insert(m.anchor_b);
  }
  return static_cast<int>(anchors.size() + beacons.size());
}

TagFix Initializer::fixOf(std::size_t f0, std::size_t f1, std::int64_t t_fix_ns, bool* from_tdoa,
                          bool anchors_once) const {
  std::vector<RangeSample> ranges;
  std::vector<TdoaSample> tdoa;
  std::vector<UltrasonicSample> ultrasonic;
  const auto beacon0 = static_cast<std::uint32_t>(p_w_anchors_.size());
  for (std::size_t k = f0; k < f1; ++k) {
    const Measurement& m = meas_[k];
    switch (m.kind) {
      case Measurement::Kind::kRange: {
        RangeSample r;
        r.t_ns = m.t_ns;
        r.anchor_id = m.anchor;
        r.range_m = m.value_m;
        ranges.push_back(r);
        break;
      }
      case Measurement::Kind::kTdoa: {
        TdoaSample t;
        t.t_ns = m.t_ns;
        t.anchor_a = m.anchor;
        t.anchor_b = m.anchor_b;
        t.diff_m = m.value_m;
        tdoa.push_back(t);
        break;
      }
      case Measurement::Kind::kUltrasonic: {
        UltrasonicSample u;
        u.t_ns = m.t_ns;
        u.anchor_id = beacon0 + m.anchor;  // beacons follow the anchors in p_w_fix_sources_
        u.range_m = m.value_m;
        ultrasonic.push_back(u);
        break;
      }
    }
  }
  *from_tdoa = false;
  TagFix fix;
  if (!ranges.empty()) {
    fix = multilaterate(ranges, t_fix_ns, p_w_anchors_, params_.fix);
    if (anchors_once && fix.anchors_used > 0) {
      fix.cov_p_w *= std::max(1.0, static_cast<double>(fix.inliers) / static_cast<double>(fix.anchors_used));
    }
    // The multilateration knows no lever arms: with several antennas its
    // point lies somewhere among them (a review's office case, antennas 0.6 m
    // apart: 0.50 m off, claiming 0.16-0.23 m). Their spread joins its covariance.
    const double spread_m = antennaSpreadM();
    if (spread_m > 0.0) fix.cov_p_w += Mat3::Identity() * (0.25 * spread_m * spread_m);
  }
  if (fix.valid || (tdoa.empty() && ultrasonic.empty())) return fix;
  *from_tdoa = true;
  return tagFixOf(locateTdoa(tdoa, ultrasonic, t_fix_ns, p_w_fix_sources_, params_.tdoa_fix));
}

double Initializer::antennaSpreadM() const {
  const std::vector<TagLeverArm>& arms = params_.graph.tag_lever_arms;
  double spread_m = 0.0;
  for (const TagLeverArm& a : arms) {
    spread_m = std::max(spread_m, (a.p_b_m - params_.graph.p_b_tag).norm());
    for (const TagLeverArm& b : arms) spread_m = std::max(spread_m, (a.p_b_m - b.p_b_m).norm());
  }
  return spread_m;
}

Initializer::AlignedWindow Initializer::alignWindow(std::int64_t window_ns, std::int64_t t_now, std::size_t end,
                                                   double fix_max_window_s) const {
  const InitializerParams& P = params_;
  AlignedWindow w;
  w.end = end;
  w.begin = rangeIndexFrom(meas_, std::max({imu_.front().t_ns, data_start_ns_, t_now - window_ns}));
  if (w.begin >= end) {
    w.message = strprintf("waiting: no ranges in the last %.1f s", toS(window_ns));
    return w;
  }
  const std::span<const Measurement> window(meas_.data() + w.begin, end - w.begin);
  const std::int64_t t_w0 = window.front().t_ns;

  const int heard = sourcesHeard(w.begin, end);
  const int needed = P.height_band.enabled ? std::min(3, P.fix.min_anchors) : P.fix.min_anchors;
  if (heard < needed) {
    w.state = InitState::kTooFewAnchors;
    w.message = strprintf("waiting: %d anchors heard, need %d", heard, P.fix.min_anchors);
    if (P.height_band.enabled && P.fix.min_anchors > 3) w.message += " (3 with the height band)";
    return w;
  }
  if (static_cast<int>(window.size()) < P.min_alignment_ranges) {
    w.message = strprintf("waiting: %zu ranges in the window, need %d", window.size(), P.min_alignment_ranges);
    return w;
  }
  const std::size_t i0 = imuIndexAt(imu_, t_w0);
  const std::span<const ImuSample> imu(imu_.data() + i0, imu_.size() - i0);

  // 1. A fix near the window start (its own window grown until it holds
  // enough anchors and measurements); if that fails, a little later.
  TagFix first_fix;
  bool have_fix = false;
  for (int k = 0; k < kFixStarts && !have_fix; ++k) {
    const std::size_t f0 = rangeIndexFrom(meas_, t_w0 + toNs(k * P.fix_window_s));
    if (f0 >= end) break;
    const std::int64_t t_fix = meas_[f0].t_ns;
    std::size_t f1 = f0;
    for (double len = P.fix_window_s;; len = std::min(fix_max_window_s, 1.5 * len)) {
      f1 = std::min(end, rangeIndexFrom(meas_, t_fix + toNs(len)));
      if (enoughForFix(f0, f1) || len >= fix_max_window_s || f1 >= end) break;
    }
    w.fix = fixOf(f0, f1, t_fix, &w.fix_from_tdoa);
    if (k == 0) first_fix = w.fix;
    have_fix = w.fix.valid;
  }
  if (!have_fix) {
    w.fix_failed = true;
    w.state = first_fix.anchors_heard < needed ? InitState::kTooFewAnchors : InitState::kPoorFix;
    w.message = "waiting: " + first_fix.message;
    return w;
  }
  const Vec3 p_tag_w0 = w.fix.p_w_tag + w.fix.v_w * toS(t_w0 - w.fix.t_ns);

  // 2. Roll and pitch from gravity.
  w.gravity = alignGravity(imu, t_w0, t_now, P.graph.imu.gravity_m_s2, P.gravity);
  if (!w.gravity.valid) {
    w.state = InitState::kNoGravity;
    w.message = "waiting: " + w.gravity.message;
    return w;
  }

  // 3. Yaw (and a first trajectory) by range-inertial alignment.
  w.alignment = alignRangeInertial(imu, window, t_w0, p_w_anchors_, w.gravity, p_tag_w0, w.fix.v_w, P.alignment);
  const AlignmentResult& a = w.alignment;
  if (!a.valid) {
    w.state = InitState::kPoorFix;
    w.message = "waiting: alignment failed: " + a.message;
    return w;
  }
  // Yaw at the window's end, where the batch hands over: at its start the
  // unresolved gyro bias adds up to 0.01 rad/s x the window (alignment.h).
  const double gap_scale = std::min(a.noiseScale(), P.max_yaw_gap_noise_scale);
  const double min_gap = P.min_yaw_cost_gap * gap_scale * gap_scale;
  if (a.yaw_sigma_end_rad > P.max_alignment_yaw_sigma_rad || a.second_cost_gap < min_gap) {
    w.state = InitState::kYawUnobservable;
    w.message = strprintf("yaw not observable yet: moved %.1f m, horizontal speed change %.2f m/s, yaw sigma %.1f deg",
                          a.moved_m, a.horizontal_dv_m_s, a.yaw_sigma_end_rad * kRadToDeg);
    if (std::isfinite(a.second_cost_gap)) {
      w.message += strprintf(", another yaw fits almost as well (cost +%.1f, needs +%.1f at noise scale %.1f)",
                             a.second_cost_gap, min_gap, gap_scale);
    }
    return w;
  }
  const double cost_per_range = a.measurement_cost / std::max(1, a.measurements);
  const double factor = heavyNlosFactor(t_now, a.ranges, a.short_ranges, a.measurements);
  if (cost_per_range > factor * P.max_alignment_cost_per_range) {
    w.state = InitState::kPoorFix;
    w.message = strprintf("waiting: ranges disagree with the IMU motion (cost per range %.2f, %d of %d ranges inliers",
                          cost_per_range, a.inliers, a.measurements);
    if (a.ranges > 0) w.message += strprintf(", %d short", a.short_ranges);
    w.message += ")";
    return w;
  }
  w.heavy_nlos = cost_per_range > P.max_alignment_cost_per_range;
  w.ok = true;
  return w;
}

double Initializer::heavyNlosFactor(std::int64_t t_now, int ranges, int short_ranges, int measurements) const {
  const InitializerParams& P = params_;
  // From the first two-way range: IMU time before ranging comes up is no wait.
  const bool waited = first_range_ns_ && toS(t_now - *first_range_ns_) >= P.heavy_nlos_after_s;
  const bool mostly_ranges = ranges > 0 && 2 * ranges >= measurements;  // the sign test needs two-way ranges
  const bool few_short = short_ranges <= P.max_short_range_share * ranges;
  return waited && mostly_ranges && few_short ? P.heavy_nlos_cost_factor : 1.0;
}

}  // namespace rilo
