#include "estimation/tracking/localizer.h"


#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/noise_model_factory.h"
#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/smoother/sliding_window_smoother.h"
#include "estimation/tracking/ekf_estimator.h"

namespace rilo {

void LocalizerParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("LocalizerParams.") + field + " " + rule);
  };
  if (!(max_speed_m_s > 0.0)) fail("max_speed_m_s", "must be > 0");
  if (!(max_accel_bias_m_s2 > 0.0)) fail("max_accel_bias_m_s2", "must be > 0");
  if (!(max_gyro_bias_rad_s > 0.0)) fail("max_gyro_bias_rad_s", "must be > 0");
  if (!(max_imu_gap_s > 0.0)) fail("max_imu_gap_s", "must be > 0");
  if (!(max_outside_anchors_m > 0.0)) fail("max_outside_anchors_m", "must be > 0 (+inf: off)");
  if (max_consecutive_rejections < 1) fail("max_consecutive_rejections", "must be >= 1");
  range_consistency.validate();
  flagged_excess.validate();
  los_gap.validate();
  rx_level_envelope.validate();
  nlos_memory.validate();
  range_repeats.validate();
  if (rejection_window < 0 || rejection_window > 1'000'000) fail("rejection_window", "must be in [0, 1e6] (0: off)");
  if (!(max_rejection_share >= 0.0 && max_rejection_share < 1.0)) fail("max_rejection_share", "must be in [0, 1)");
  if (!(init_attempt_budget_s >= 0.0)) fail("init_attempt_budget_s", "must be >= 0 (+inf: no bound)");
  height_band.validate("LocalizerParams.height_band");
  if (with_tdoa.state_window_ns < 0 || with_tdoa.state_window_ns >= graph.max_state_interval_ns) {
    fail("with_tdoa.state_window_ns", "must be in [0, graph.max_state_interval_ns) (0: the graph's window)");
  }
  if (vertical_speed_sigma_m_s && !(*vertical_speed_sigma_m_s >= 0.0 && std::isfinite(*vertical_speed_sigma_m_s))) {
    fail("vertical_speed_sigma_m_s", "must be finite and >= 0 (or unset: auto)");
  }
  if (!(zero_velocity_sigma_m_s >= 0.0 && std::isfinite(zero_velocity_sigma_m_s))) {
    fail("zero_velocity_sigma_m_s", "must be finite and >= 0 (0: off)");
  }
  if (!(graph.vertical_speed_correlation_s > 0.0 && std::isfinite(graph.vertical_speed_correlation_s))) {
    fail("graph.vertical_speed_correlation_s", "must be finite and > 0");
  }
  smoother.validate();
  sliding_window.validate();
  init.validate();
}

const std::vector<std::string>& estimatorNames() {
  static const std::vector<std::string> kNames = [] {
    std::vector<std::string> names;
    for (const auto& [name, method] : kSmootherMethodNames) names.emplace_back(name);
    names.insert(names.end(), {"sliding-window", "ekf"});
    return names;
  }();
  return kNames;
}

void setEstimatorByName(LocalizerParams& params, const std::string& name) {
  if (name == "ekf") {
    params.estimator = LocalizerParams::Estimator::kEkf;
    return;
  }
  if (name == "sliding-window") {
    params.estimator = LocalizerParams::Estimator::kSlidingWindow;
    return;
  }
  try {
    params.smoother.method = smootherMethodFromName(name);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument("unknown estimator '" + name + "' (expected d-isam2, isam2, dogleg, sliding-window or ekf)");
  }
  params.estimator = LocalizerParams::Estimator::kSmoother;
}

namespace {

double elapsedS(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

/// The single height band and vertical speed settings pushed into the parts;
/// a band whose floor does not fit the anchors is dropped (see plausibleFor).
LocalizerParams resolved(LocalizerParams p, const std::vector<Vec3>& p_w_anchors, std::string& note) {
  if (p.height_band.enabled && !p.height_band.plausibleFor(p_w_anchors)) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "height band off: the anchors do not look mounted 1-6 m above a floor at z = %.2f m", p.height_band.floor_z_m);
    note = text;
    p.height_band.enabled = false;
  }
  p.init.height_band = p.height_band;
  p.graph.height_band = p.track_height_band ? p.height_band : HeightBand::off();
  p.graph.vertical_speed_sigma_m_s = p.vertical_speed_sigma_m_s.value_or(0.0);  // auto: see startTracking
  // The initializer's batch window and small solvers use the estimator's
  // graph (IMU model, noise, lever arms, TDoA and ultrasonic settings).
  p.graph.zero_velocity_sigma_m_s = p.zero_velocity_sigma_m_s;
  p.init.graph = p.graph;
  p.init.graph.zero_velocity_sigma_m_s = 0.0;  // its batch has its own (InitializerParams)
  p.init.tdoa_state_window_ns = p.with_tdoa.state_window_ns;
  return p;
}

/// Two-way ranges per second in `buffered` (0 with fewer than two, or over less than a second).
double twoWayRangeRateHz(const std::vector<Measurement>& buffered) {
  int count = 0;
  std::int64_t first_ns = 0, last_ns = 0;
  for (const Measurement& m : buffered) {
    if (m.kind != Measurement::Kind::kRange) continue;
    if (count == 0) first_ns = m.t_ns;
    last_ns = std::max(last_ns, m.t_ns);
    ++count;
  }
  const double span_s = static_cast<double>(last_ns - first_ns) * 1e-9;
  return count >= 2 && span_s >= 1.0 ? static_cast<double>(count - 1) / span_s : 0.0;
}

/// The calibration runs only where the receiver's indicator is in use.
LosGapParams losGapFor(const LocalizerParams& p) {
  LosGapParams g = p.los_gap;
  g.enabled = g.enabled && p.graph.range_loss == "asymmetric" && std::isfinite(p.graph.range_noise.nlos_power_gap_db);
  return g;
}

/// The residual (m) beyond which the mixture takes a range as NLOS, where a
/// flag is read (the asymmetric model with a finite threshold, range_model.h);
/// NaN elsewhere: the memory is off.
double nlosDecisionPointM(const LocalizerParams& p) {
  const RangeNoiseParams& n = p.graph.range_noise;
  if (p.graph.range_loss != "asymmetric" || !std::isfinite(n.nlos_power_gap_db)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const RobustLossPtr loss = makeRangeLoss(p.graph.range_loss, n);
  const auto* mixture = dynamic_cast<const AsymmetricLoss*>(loss.get());
  return mixture != nullptr ? mixture->decisionPoint() * n.sigma_m : std::numeric_limits<double>::quiet_NaN();
}

/// The envelope learns only where a flag is read: the asymmetric model with a
/// finite threshold (range_model.h), as the gap calibration.
RxLevelEnvelopeParams rxLevelEnvelopeFor(const LocalizerParams& p) {
  RxLevelEnvelopeParams e = p.rx_level_envelope;
  e.enabled = e.enabled && p.graph.range_loss == "asymmetric" && std::isfinite(p.graph.range_noise.nlos_power_gap_db);
  return e;
}

}  // namespace

Localizer::Localizer(std::vector<Vec3> p_w_anchors, LocalizerParams params)
    : p_w_anchors_(std::move(p_w_anchors)),
      params_(resolved(std::move(params), p_w_anchors_, height_band_note_)),
      tdoa_model_(tdoaModelParams(params_.graph), params_.graph.range_noise),
      initializer_(p_w_anchors_, params_.init),
      consistency_(p_w_anchors_, params_.graph.p_b_tag, params_.graph.range_noise.sigma_m,
                   params_.graph.same_state_window_ns, params_.range_consistency,
                   params_.graph.range_noise.nlos_power_gap_db, losGapFor(params_), params_.graph.tag_lever_arms,
                   NlosMemory(p_w_anchors_.size(), nlosDecisionPointM(params_), params_.nlos_memory)),
      rx_level_envelope_(rxLevelEnvelopeFor(params_)),
      screen_(params_.screen) {
  params_.validate();
  tracking_range_noise_ = params_.graph.range_noise;
  // Flagged ranges take the estimated shift, whether modelled by the NLOS
  // component or the mixture (range_model.h).
  const RangeNoiseParams& n = params_.graph.range_noise;
  estimate_flagged_excess_ = params_.flagged_excess.quantile > 0.0 && params_.graph.range_loss == "asymmetric" &&
                             std::isfinite(n.nlos_power_gap_db);
  if (params_.rejection_window > 0) rejection_window_.emplace(params_.rejection_window, params_.max_rejection_share);
}

Localizer::~Localizer() { abandonInitAttempt(); }

void Localizer::setInitRunner(std::unique_ptr<InitAttemptRunner> runner) {
  abandonInitAttempt();
  init_runner_ = std::move(runner);
}

void Localizer::abandonInitAttempt() {
  if (!pending_) return;
  pending_->cancel.store(true, std::memory_order_relaxed);
  init_runner_->wait();
  pending_.reset();
}

void Localizer::addImu(const ImuSample& sample) {
  if (!screen_.admit(sample)) return;
  if (have_imu_ && phase_ == Phase::kTracking &&
      static_cast<double>(sample.t_ns - last_imu_ns_) * 1e-9 > params_.max_imu_gap_s) {
    char why[96];
    std::snprintf(why, sizeof why, "IMU silent for %.2f s", static_cast<double>(sample.t_ns - last_imu_ns_) * 1e-9);
    fail(why);
  }
  have_imu_ = true;
  last_imu_ns_ = sample.t_ns;
  if (phase_ == Phase::kTracking) {
    guarded([&] { estimator_->addImu(sample); });
  } else {
    initializer_.addImu(sample);
  }
}

void Localizer::addRange(const RangeSample& received) {
  if (received.anchor_id >= p_w_anchors_.size()) return;  // unknown anchor: the initializer counts these
  if (!screen_.admit(received)) return;
  if (phase_ == Phase::kTracking) {
    const RangeSample sample = withNlosMemory(received, withRxLevelIndicator(received));
    if (sample.nlos_from_memory) ++ranges_flagged_by_memory_;
    ranging_support_.note(sample.t_ns);
    consistency_.onRange(sample);
    guarded([&] { estimator_->addRange(sample); });
  } else {
    RangeSample sample = withRxLevelIndicator(received);
    sample.nlos_from_memory = false;  // the memory is the tracker's: a start takes the mixture's own verdicts
    initializer_.addRange(sample);
  }
}

RangeSample Localizer::withNlosMemory(const RangeSample& received, RangeSample sample) const {
  // The receiver's own first-path power is better evidence than the memory
  // (nlos_memory.h); only ranges without it are marked.
  sample.nlos_from_memory = std::isnan(received.fp_power_dbm) &&
                            consistency_.nlosMemory().remembersNlos(sample.anchor_id, sample.tag_id, sample.t_ns);
  return sample;
}

RangeSample Localizer::withRxLevelIndicator(const RangeSample& sample) {
  if (!std::isnan(sample.fp_power_dbm) || !std::isfinite(sample.rssi_dbm)) return sample;
  rx_level_envelope_.add(sample.range_m, sample.rssi_dbm);
  const double deficit_db = rx_level_envelope_.deficitDb(sample.range_m, sample.rssi_dbm);
  if (!std::isfinite(deficit_db)) return sample;
  // The first-path power a receiver would report with this gap: everything
  // downstream reads the indicator as RX level minus first-path power. The
  // two scales differ in where LOS ends: a LOS first path sits within a few
  // dB of the RX level (the calibration's reference, gaps up to
  // los_gap.min_gap_db), while a LOS RX level sits at or above the envelope
  // (deficit 0). So a deficit d reads as the gap min_gap_db + d: ranges at
  // the envelope are the calibration's LOS reference, and it learns from
  // the residuals how many dB below it the excess begins (up to
  // los_gap.rx_level_max_gap_db, a 6 dB deficit: not the vendor's 6 dB gap,
  // los_gap_calibration.h). Read as a gap of d, the flag began at the
  // calibration's 3-3.5 dB floor, well inside the NLOS cluster: on the
  // independent office sims LOS ranges sit about 5 dB above an all-range
  // path-loss fit and NLOS ones 2 dB below it, so half the NLOS ranges went
  // unflagged (docs/noise-models.md, session 31). A range at or above the
  // envelope sits mid-bin below the reference edge: at the edge itself,
  // rounding in rssi - fp put some into the first candidate bin.
  const LosGapParams& cal = params_.los_gap;
  const double reference_top_db = std::floor(cal.min_gap_db / cal.bin_db) * cal.bin_db;  // the last reference bin's edge
  const double gap_db = deficit_db > 0.0 ? cal.min_gap_db + deficit_db : reference_top_db - 0.5 * cal.bin_db;
  RangeSample s = sample;
  s.fp_power_dbm = s.rssi_dbm - gap_db;
  s.fp_from_rx_level = true;  // its flag takes no learnt shift (range_model.h)
  return s;
}

bool Localizer::addTdoa(const TdoaSample& sample) {
  if (sample.anchor_a >= p_w_anchors_.size() || sample.anchor_b >= p_w_anchors_.size()) return false;  // as addRange
  if (!screen_.admit(sample)) return false;
  if (tdoa_model_.gated(Measurement::of(sample))) {
    ++tdoa_rows_gated_;
    return false;
  }
  if (phase_ == Phase::kTracking) {
    ranging_support_.note(sample.t_ns);
    guarded([&] { estimator_->addTdoa(sample); });
  } else {
    initializer_.addTdoa(sample);
  }
  return true;
}

void Localizer::addUltrasonic(const UltrasonicSample& sample) {
  if (sample.anchor_id >= params_.graph.p_w_ultrasonic.size()) return;  // unknown beacon
  if (!screen_.admit(sample)) return;
  if (phase_ == Phase::kTracking) {
    ranging_support_.note(sample.t_ns);
    guarded([&] { estimator_->addUltrasonic(sample); });
  } else {
    initializer_.addUltrasonic(sample);
  }
}

int Localizer::process(std::vector<UpdateStats>* stats) {
  if (phase_ == Phase::kInitializing) {
    if (!(init_runner_ ? initializeElsewhere() : initializer_.process())) return 0;
    startTracking();
    if (phase_ != Phase::kTracking) return 0;
  }
  scratch_.clear();
  int updates = 0;
  guarded([&] { updates = estimator_->process(&scratch_); });
  if (phase_ != Phase::kTracking) return updates;
  for (const UpdateStats& s : scratch_) {
    if (stats) stats->push_back(s);
    checkHealth(s);
    if (phase_ != Phase::kTracking) break;
  }
  if (phase_ == Phase::kTracking && updates > 0) checkConsistency();
  return updates;
}

void Localizer::finish() {
  finished_ = true;  // no attempt starts after this one
  if (phase_ == Phase::kInitializing && pending_) {
    // The end of the data: the running attempt is the last one, take it,
    // within its budget.
    const double left_s = params_.init_attempt_budget_s - elapsedS(pending_->started);
    if (!(left_s > 0.0 && init_runner_->waitFor(left_s))) {
      pending_->cancel.store(true, std::memory_order_relaxed);
      init_runner_->wait();
    }
    if (initializeElsewhere()) startTracking();
  }
  if (phase_ == Phase::kTracking) guarded([&] { estimator_->finish(); });
}

bool Localizer::initializeElsewhere() {
  const bool due = initializer_.attemptDue();  // also refreshes the provisional fix
  if (pending_) {
    if (!init_runner_->idle()) {
      if (elapsedS(pending_->started) > params_.init_attempt_budget_s && !pending_->cancel.load(std::memory_order_relaxed)) {
        pending_->cancel.store(true, std::memory_order_relaxed);
        ++init_attempts_over_budget_;
      }
      return false;
    }
    initializer_.adoptAttempt(std::move(pending_->initializer));
    pending_.reset();
    return initializer_.initialized();
  }
  if (!due || finished_) return false;
  try {
    // A copy of the buffers (1-3 MB: 54 s of 200-800 Hz IMU and the
    // ranges): the attempt reads them while this thread appends to the
    // originals.
    pending_ = std::make_unique<PendingAttempt>(initializer_);
    pending_->initializer.setCancelFlag(&pending_->cancel);
    init_runner_->start([attempt = pending_.get()] { attempt->initializer.attempt(); });
    return false;
  } catch (const std::exception&) {
    // No memory for the copy (or no runner): this attempt runs here, where
    // Initializer::attempt reports its own failures.
    pending_.reset();
    return initializer_.attempt();
  }
}

template <typename F>
void Localizer::guarded(F&& f) {
  // A diverged state can make the estimator refuse its input (a bias so
  // large that one preintegration window rotates more than it supports):
  // that is a tracking failure to recover from, never a crash.
  try {
    f();
  } catch (const std::exception& e) {
    fail(std::string("estimator error: ") + e.what());
  }
}

void Localizer::startTracking() {
  RangeImuGraphParams graph = params_.graph;
  RangeImuStreamOptions stream = params_.stream;
  stream.learn_carry_height = graph.height_band.learn_carry_height;
  stream.range_repeats = params_.range_repeats;
  // The data the tracker starts on say which ranging is in use.
  const std::vector<Measurement>& buffered = initializer_.measurementBuffer();
  const bool tdoa = std::any_of(buffered.begin(), buffered.end(),
                                [](const Measurement& m) { return m.kind == Measurement::Kind::kTdoa; });
  if (!params_.vertical_speed_sigma_m_s) graph.vertical_speed_sigma_m_s = defaultVerticalSpeedSigma(tdoa);  // "auto"
  if (tdoa && params_.with_tdoa.state_window_ns > 0) graph.same_state_window_ns = params_.with_tdoa.state_window_ns;
  // Unless configured, flagged ranges get the component scale for the
  // two-way ranging rate of those data (flagged_scale_reference_hz).
  RangeNoiseParams& noise = graph.range_noise;
  if (noise.flagged_nlos_component && !noise.flagged_nlos_scale_m) {
    noise.flagged_nlos_scale_m = noise.flaggedComponentScaleAt(twoWayRangeRateHz(buffered));
  }
  tracking_range_noise_ = noise;
  tracking_started_ = true;
  EkfParams ekf = params_.ekf;
  if (tdoa && params_.with_tdoa.dynamic_covariance) {
    stream.dynamic_covariance.enabled = true;
    ekf.dynamic_covariance.enabled = true;
  }
  tracking_vertical_speed_sigma_m_s_ = graph.vertical_speed_sigma_m_s;
  tracking_state_window_ns_ = graph.same_state_window_ns;
  consistency_.setStateWindow(graph.same_state_window_ns);
  tracking_dynamic_covariance_ = params_.estimator == LocalizerParams::Estimator::kEkf
                                     ? ekf.dynamic_covariance.enabled
                                     : stream.dynamic_covariance.enabled;
  if (params_.estimator == LocalizerParams::Estimator::kEkf) {
    estimator_ = std::make_unique<EkfEstimator>(p_w_anchors_, graph, ekf);
  } else if (params_.estimator == LocalizerParams::Estimator::kSlidingWindow) {
    estimator_ = std::make_unique<RangeImuEstimator>(
        p_w_anchors_, graph, std::make_unique<SlidingWindowSmoother>(params_.sliding_window), stream);
  } else {
    estimator_ = std::make_unique<RangeImuEstimator>(p_w_anchors_, graph,
                                                     std::make_unique<BayesTreeSmoother>(params_.smoother), stream);
  }
  // The new estimator starts without a shift (not the component's mode)
  // until the estimate has enough flagged ranges.
  flagged_excess_m_ = 0.0;
  if (estimate_flagged_excess_) estimator_->setFlaggedExcess(flagged_excess_m_);
  gap_db_in_use_ = params_.graph.range_noise.nlos_power_gap_db;  // the calibration restarts below
  // Starts at the initializer's state and replays what it buffered after
  // it, so no sample is lost.
  phase_ = Phase::kTracking;
  guarded([&] { handOver(initializer_, *estimator_); });
  if (phase_ != Phase::kTracking) return;
  consecutive_rejections_ = 0;
  consistency_.reset();
  ranging_support_.reset();
  if (rejection_window_) rejection_window_->reset();
  ++initializations_;
}

void Localizer::checkHealth(const UpdateStats& stats) {
  const StateEstimate& s = estimator_->latest();
  const double t_s = static_cast<double>(s.t_ns) * 1e-9;
  char why[128];
  const double speed = s.v_w.norm();
  const Vec6 b = s.bias.vector();
  if (!std::isfinite(speed) || !s.T_w_b.p.allFinite() || !b.allFinite()) {
    std::snprintf(why, sizeof why, "non-finite state at t=%.3f s", t_s);
    fail(why);
  } else if (speed > params_.max_speed_m_s) {
    std::snprintf(why, sizeof why, "speed %.1f m/s at t=%.3f s (limit %.1f)", speed, t_s, params_.max_speed_m_s);
    fail(why);
  } else if (const double outside = anchor_box_.outside(s.T_w_b.p);
             outside > params_.max_outside_anchors_m && ranging_support_.supports(s.t_ns)) {
    std::snprintf(why, sizeof why, "position (%.1f, %.1f) m is %.1f m outside the anchors' area at t=%.3f s (limit %.1f)",
                  s.T_w_b.p.x(), s.T_w_b.p.y(), outside, t_s, params_.max_outside_anchors_m);
    fail(why);
  } else if (b.head<3>().cwiseAbs().maxCoeff() > params_.max_accel_bias_m_s2 ||
             b.tail<3>().cwiseAbs().maxCoeff() > params_.max_gyro_bias_rad_s) {
    std::snprintf(why, sizeof why, "implausible IMU bias (accel %.2f m/s^2, gyro %.3f rad/s) at t=%.3f s",
                  b.head<3>().cwiseAbs().maxCoeff(), b.tail<3>().cwiseAbs().maxCoeff(), t_s);
    fail(why);
  } else if (!stats.step_accepted && ++consecutive_rejections_ >= params_.max_consecutive_rejections) {
    std::snprintf(why, sizeof why, "%d updates in a row kept the previous estimate at t=%.3f s", consecutive_rejections_, t_s);
    fail(why);
  } else if (rejection_window_ && rejection_window_->note(stats.step_accepted)) {
    std::snprintf(why, sizeof why, "%d of the last %d updates kept the previous estimate at t=%.3f s (limit %.0f %%)",
                  rejection_window_->rejected(), rejection_window_->length(), t_s, 100.0 * params_.max_rejection_share);
    fail(why);
  } else if (stats.step_accepted) {
    consecutive_rejections_ = 0;
  }
}

void Localizer::checkConsistency() {
  const StateEstimate& s = estimator_->latest();
  const bool consistent = consistency_.judge(s.t_ns, s.T_w_b, s.v_w);
  if (estimate_flagged_excess_) {
    const FlaggedExcessParams& fx = params_.flagged_excess;
    const double e = consistency_.flaggedQuantile(fx.quantile, fx.min_ranges);
    if (std::isfinite(e)) {
      flagged_excess_m_ = std::clamp(e, 0.0, fx.max_m);
      estimator_->setFlaggedExcess(flagged_excess_m_);
    }
  }
  if (const double gap_db = consistency_.flagGapDb(); gap_db != gap_db_in_use_) {
    gap_db_in_use_ = gap_db;
    estimator_->setNlosGapDb(gap_db);
  }
  estimator_->setGapExcess(consistency_.losGap().excessTable());  // 32 doubles: a copy per update is cheaper than tracking changes
  if (consistent) return;
  char why[160];
  std::snprintf(why, sizeof why, "%.0f%% of the last %d ranges much shorter than the estimate predicts at t=%.3f s",
                100.0 * consistency_.shortShare(), consistency_.judgedInWindow(), static_cast<double>(s.t_ns) * 1e-9);
  fail(why);
}

void Localizer::fail(std::string why) {
  abandonInitAttempt();  // none runs while tracking; an attempt on data before the failure must never be adopted
  last_failure_ = std::move(why);
  if (phase_ == Phase::kTracking) ++reinitializations_;
  phase_ = Phase::kInitializing;
  if (estimator_) standstill_priors_ended_ += estimator_->standstillPriors();
  estimator_.reset();
  initializer_.reset();
}

std::optional<Localizer::ProvisionalPosition> Localizer::provisionalPosition() const {
  const std::optional<ProvisionalFix>& fix = initializer_.provisionalFix();
  if (phase_ == Phase::kTracking || !fix) return std::nullopt;
  const Vec3& lever = params_.graph.p_b_tag;
  ProvisionalPosition out;
  out.t_ns = fix->t_ns;
  out.p_w_b = fix->p_w_tag - Vec3(0.0, 0.0, lever.z());
  // Any yaw: the horizontal lever arm lies anywhere on its circle (variance r^2 / 2 per axis).
  const double r2 = lever.head<2>().squaredNorm();
  out.cov_p_w = fix->cov_p_w;
  out.cov_p_w(0, 0) += 0.5 * r2;
  out.cov_p_w(1, 1) += 0.5 * r2;
  out.sequence = fix->sequence;
  return out;
}

std::optional<CovarianceBlock> Localizer::latestPoseCovariance() {
  if (!tracking()) return std::nullopt;
  return estimator_->latestPoseCovariance();
}

std::optional<CovarianceBlock> Localizer::latestVelocityCovariance() {
  if (!tracking()) return std::nullopt;
  return estimator_->latestVelocityCovariance();
}

}  // namespace rilo
