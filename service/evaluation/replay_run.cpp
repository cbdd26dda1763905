#include "evaluation/replay_run.h"

#include <algorithm>
#include <iterator>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

namespace rilo {

namespace {

ImuParams imuParamsFrom(const RecordingMeta& meta) {
  ImuParams imu;
  imu.gravity_m_s2 = meta.gravity_m_s2;
  if (meta.gyro_noise_density) imu.gyro_noise_density = *meta.gyro_noise_density;
  if (meta.accel_noise_density) imu.accel_noise_density = *meta.accel_noise_density;
  if (meta.gyro_bias_random_walk) imu.gyro_bias_random_walk = *meta.gyro_bias_random_walk;
  if (meta.accel_bias_random_walk) imu.accel_bias_random_walk = *meta.accel_bias_random_walk;
  imu.gyro_bias_tau_s = ImuParams::kRandomWalk;
  imu.accel_bias_tau_s = ImuParams::kRandomWalk;
  return imu;
}

/// The recording's device where its meta says it; the rest stays `graph`'s
/// (ReplaySettings::device_from_recording). Gravity stays the
/// configuration's: RecordingMeta cannot tell a stated 9.81 from none (a
/// meta.yaml without it reads 9.81), and would override a configured site's.
void takeDeviceFrom(const RecordingMeta& meta, RangeImuGraphParams& graph) {
  ImuParams& imu = graph.imu;
  if (meta.gyro_noise_density) imu.gyro_noise_density = *meta.gyro_noise_density;
  if (meta.accel_noise_density) imu.accel_noise_density = *meta.accel_noise_density;
  if (meta.gyro_bias_random_walk) imu.gyro_bias_random_walk = *meta.gyro_bias_random_walk;
  if (meta.accel_bias_random_walk) imu.accel_bias_random_walk = *meta.accel_bias_random_walk;
  if (meta.uwb_lever_arm_m) graph.p_b_tag = *meta.uwb_lever_arm_m;
  if (meta.ultrasonic_lever_arm_m) graph.p_b_ultrasonic = *meta.ultrasonic_lever_arm_m;
}

/// The recording's antennas (tags.csv), each range predicted from its own;
/// the lowest id also stands for the single antenna (height band, TDoA,
/// position-only fix). Nothing to take without tags.csv.
void takeTagsFrom(const Recording& rec, RangeImuGraphParams& graph) {
  if (rec.tags.empty()) return;
  graph.tag_lever_arms.clear();
  const Tag* lowest = &rec.tags.front();
  for (const Tag& t : rec.tags) {
    graph.tag_lever_arms.push_back({t.id, t.p_b_tag});
    if (t.id < lowest->id) lowest = &t;
  }
  graph.p_b_tag = lowest->p_b_tag;
}

/// Uniform [0, 1) from 53 bits: the same numbers on every platform (unlike
/// std::uniform_real_distribution, whose algorithm the standard leaves open).
double unitDraw(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// One sample to feed, in the merged time order.
struct FeedItem {
  std::int64_t t_ns;
  Measurement::Kind kind;
  std::size_t index;  ///< into the kind's kept samples
};

}  // namespace

MeasurementKinds measurementKindsFromString(const std::string& list) {
  MeasurementKinds k{false, false, false};
  std::stringstream in(list);
  std::string item;
  bool any = false;
  while (std::getline(in, item, ',')) {
    if (item == "range") {
      k.range = true;
    } else if (item == "tdoa") {
      k.tdoa = true;
    } else if (item == "ultrasonic") {
      k.ultrasonic = true;
    } else {
      throw std::invalid_argument("measurements: unknown kind '" + item + "' (expected range, tdoa, ultrasonic)");
    }
    any = true;
  }
  if (!any) throw std::invalid_argument("measurements: the list is empty (expected range, tdoa, ultrasonic)");
  return k;
}

std::string toString(const MeasurementKinds& kinds) {
  std::string out;
  for (const auto& [on, name] : {std::pair{kinds.range, "range"}, std::pair{kinds.tdoa, "tdoa"},
                                 std::pair{kinds.ultrasonic, "ultrasonic"}}) {
    if (!on) continue;
    if (!out.empty()) out.push_back(',');
    out.append(name);
  }
  return out;
}

LocalizerParams localizerParamsFor(const Recording& rec, const ReplaySettings& s) {
  const bool from_service = s.service_params.has_value();
  LocalizerParams lp = s.service_params.value_or(LocalizerParams{});
  if (!from_service) {
    lp.graph.imu = imuParamsFrom(rec.meta);
    lp.graph.p_b_tag = rec.meta.uwbLeverArm();
    lp.graph.p_b_ultrasonic = rec.meta.ultrasonicLeverArm();
    takeTagsFrom(rec, lp.graph);
  } else if (s.device_from_recording) {
    takeDeviceFrom(rec.meta, lp.graph);
    takeTagsFrom(rec, lp.graph);
  }
  lp.graph.range_loss = s.noise;
  if (s.range_sigma_m) lp.graph.range_noise.sigma_m = *s.range_sigma_m;
  if (s.nlos_scale_m) lp.graph.range_noise.nlos_scale_m = *s.nlos_scale_m;
  if (s.nlos_weight) lp.graph.range_noise.nlos_weight = *s.nlos_weight;
  if (s.nlos_power_gap_db) lp.graph.range_noise.nlos_power_gap_db = *s.nlos_power_gap_db;
  if (s.flagged_nlos_weight) lp.graph.range_noise.flagged_nlos_weight = *s.flagged_nlos_weight;
  if (s.flagged_nlos_component) lp.graph.range_noise.flagged_nlos_component = *s.flagged_nlos_component;
  if (s.flagged_nlos_scale_m) lp.graph.range_noise.flagged_nlos_scale_m = *s.flagged_nlos_scale_m;
  if (s.flagged_excess_quantile) lp.flagged_excess.quantile = *s.flagged_excess_quantile;
  if (s.los_gap_calibration) lp.los_gap.enabled = *s.los_gap_calibration;
  if (s.rx_level_indicator) lp.rx_level_envelope.enabled = *s.rx_level_indicator;
  if (s.nlos_memory_s) lp.nlos_memory.window_s = *s.nlos_memory_s;
  if (s.range_error_correlation_s) lp.range_repeats.error_correlation_s = *s.range_error_correlation_s;
  if (s.max_outside_anchors_m) lp.max_outside_anchors_m = *s.max_outside_anchors_m;
  if (s.init_max_outside_anchors_m) lp.init.max_outside_anchors_m = *s.init_max_outside_anchors_m;
  if (s.init_heavy_nlos_after_s) lp.init.heavy_nlos_after_s = *s.init_heavy_nlos_after_s;
  if (s.height_band) lp.track_height_band = *s.height_band;
  if (s.floor_z_m) lp.height_band.floor_z_m = *s.floor_z_m;
  if (s.min_height_m) lp.height_band.min_height_m = *s.min_height_m;
  if (s.max_height_m) lp.height_band.max_height_m = *s.max_height_m;
  if (s.range_lever) lp.height_band.range_lever = *s.range_lever;
  if (s.height_hold_sigma_m) lp.height_band.hold_sigma_m = *s.height_hold_sigma_m;
  if (s.learn_carry_height) lp.height_band.learn_carry_height = *s.learn_carry_height;
  lp.graph.p_w_ultrasonic = ultrasonicBeaconsById(rec.anchors);
  // The vertical speed prior is the replay's own choice (with the service's
  // parameters, only an explicit one changes theirs): set here, it holds in
  // the initializer too, where the Localizer's "auto" starts with tracking
  // (two-way office sims: 0.2305 against 0.2309 m online mean, session 25).
  // The TDoA state window and per-link sigmas are the Localizer's with_tdoa;
  // explicit settings replace them for every kind of data.
  const bool tdoa_used = s.measurements.tdoa && !rec.tdoa.empty();
  if (s.vertical_speed_sigma_m_s) {
    lp.vertical_speed_sigma_m_s = *s.vertical_speed_sigma_m_s;
  } else if (!from_service) {
    lp.vertical_speed_sigma_m_s = defaultVerticalSpeedSigma(tdoa_used);
  }
  if (s.zero_velocity_sigma_m_s) lp.zero_velocity_sigma_m_s = *s.zero_velocity_sigma_m_s;
  if (s.same_state_window_ms) {
    lp.graph.same_state_window_ns = static_cast<std::int64_t>(std::llround(*s.same_state_window_ms * 1e6));
    lp.with_tdoa.state_window_ns = 0;
  }
  if (s.tdoa_sigma_m) lp.graph.tdoa_sigma_m = *s.tdoa_sigma_m;
  if (s.ultrasonic_sigma_m) lp.graph.ultrasonic_sigma_m = *s.ultrasonic_sigma_m;
  if (s.tdoa_noise) lp.graph.tdoa_loss = *s.tdoa_noise;
  if (s.ultrasonic_noise) lp.graph.ultrasonic_loss = *s.ultrasonic_noise;
  if (s.tdoa_nlos_indicator) lp.graph.tdoa_nlos_indicator = *s.tdoa_nlos_indicator;
  if (s.tdoa_flagged_noise) lp.graph.tdoa_flagged_loss = *s.tdoa_flagged_noise;
  if (s.tdoa_both_flagged_factor) lp.graph.tdoa_both_flagged_sigma_factor = *s.tdoa_both_flagged_factor;
  if (s.tdoa_one_flagged_factor) lp.graph.tdoa_one_flagged_sigma_factor = *s.tdoa_one_flagged_factor;
  if (s.tdoa_max_power_gap_db) lp.graph.tdoa_max_power_gap_db = *s.tdoa_max_power_gap_db;
  if (s.tdoa_gap_excess) lp.graph.tdoa_gap_excess.enabled = *s.tdoa_gap_excess;
  // The EKF baseline needs the per-link sigmas as much as the graph (with_tdoa
  // gives them to both): at the configured 0.15 m against the office sim's
  // 1.3-1.5 m NLOS TDoA errors its covariance collapsed to a few cm, its gate
  // refused 30-70 % of the rows and it diverged (21 re-initializations on the
  // three office sims).
  if (s.dynamic_covariance) {
    lp.stream.dynamic_covariance.enabled = *s.dynamic_covariance;
    lp.ekf.dynamic_covariance.enabled = *s.dynamic_covariance;
    lp.with_tdoa.dynamic_covariance = *s.dynamic_covariance;
  }
  // And, the replay's own choice for the baseline (rilod runs no EKF, so
  // also with service_params), a velocity that may wander
  // (EkfParams::velocity_noise_density): with the IMU's densities alone it
  // learnt a tilt from NLOS errors that persist for seconds and ran away on 4
  // of 12 office sims (issue 7).
  if (tdoa_used) lp.ekf.velocity_noise_density = kEkfTdoaVelocityNoiseDensity;
  setEstimatorByName(lp, s.smoother);
  // rilod refuses this in its configuration; a --smoother override must too.
  if (lp.smoother.dampedWithStalePreviousState()) {
    throw std::invalid_argument(SmootherParams::kDampedNeedsRecentRelinearization);
  }
  lp.smoother.lag_s = s.lag_s;
  lp.sliding_window.window_s = s.lag_s;
  return lp;
}

ReplayResult replayRecording(const Recording& rec, const ReplaySettings& settings) {
  const MeasurementKinds& kinds = settings.measurements;
  const bool has_selected = (kinds.range && !rec.ranges.empty()) || (kinds.tdoa && !rec.tdoa.empty()) ||
                            (kinds.ultrasonic && !rec.ultrasonic.empty());
  if (rec.imu.empty() || !has_selected) {
    throw std::runtime_error(rec.meta.name + ": needs imu.csv and samples of a selected measurement kind (" +
                             toString(kinds) + ")");
  }
  if (!(settings.range_hz >= 0.0)) throw std::invalid_argument("replay: range_hz must be >= 0");
  if (!(settings.reception >= 0.0 && settings.reception <= 1.0)) {
    throw std::invalid_argument("replay: reception must be in [0, 1]");
  }
  if (settings.same_state_window_ms && !(*settings.same_state_window_ms >= 0.0)) {
    throw std::invalid_argument("replay: same_state_window_ms must be >= 0");
  }
  const LocalizerParams params = localizerParamsFor(rec, settings);
  Localizer localizer(uwbAnchorsById(rec.anchors), params);

  ReplayResult out;
  std::vector<UpdateStats> stats;
  MeasurementCounts& counts = out.measurements;
  counts.range = {rec.ranges.size(), 0, 0, kinds.range};
  counts.tdoa = {rec.tdoa.size(), 0, 0, kinds.tdoa};
  counts.ultrasonic = {rec.ultrasonic.size(), 0, 0, kinds.ultrasonic};

  // Ranges: thinned, then each packet received with probability `reception`.
  std::vector<RangeSample> ranges;
  if (kinds.range) {
    RangeThinningOptions thinning;
    thinning.rate_hz = settings.range_hz;
    thinning.mode = settings.thinning;
    ranges = thinRanges(rec.ranges, thinning);
    if (settings.reception < 1.0) {
      std::mt19937_64 rng(settings.reception_seed * 2 + 1);  // a stream per kind: dropping ranges ignores TDoA
      const std::size_t before = ranges.size();
      std::erase_if(ranges, [&](const RangeSample&) { return unitDraw(rng) >= settings.reception; });
      counts.range.dropped = before - ranges.size();
    }
  }
  // TDoA: the rows of one time are one received packet, kept or lost together.
  std::vector<TdoaSample> tdoa;
  if (kinds.tdoa) {
    std::mt19937_64 rng(settings.reception_seed * 2 + 2);
    bool keep = true;
    for (std::size_t k = 0; k < rec.tdoa.size(); ++k) {
      if (settings.reception < 1.0 && (k == 0 || rec.tdoa[k].t_ns != rec.tdoa[k - 1].t_ns)) {
        keep = unitDraw(rng) < settings.reception;
      }
      if (keep) {
        tdoa.push_back(rec.tdoa[k]);
      } else {
        ++counts.tdoa.dropped;
      }
    }
  }
  const std::vector<UltrasonicSample> no_ultrasonic;
  const std::vector<UltrasonicSample>& ultrasonic = kinds.ultrasonic ? rec.ultrasonic : no_ultrasonic;
  out.ranges_used = counts.range.used = ranges.size();
  counts.tdoa.used = tdoa.size();
  {
    const TdoaModel tdoa_model(tdoaModelParams(params.graph), params.graph.range_noise);
    for (const TdoaSample& row : tdoa) {
      const Measurement m = Measurement::of(row);
      if (tdoa_model.gated(m)) continue;  // counted by the Localizer (deep_nlos)
      const int n = tdoa_model.flaggedPackets(m);
      counts.tdoa.flagged_one += n == 1 ? 1 : 0;
      counts.tdoa.flagged_both += n == 2 ? 1 : 0;
    }
  }
  counts.ultrasonic.used = ultrasonic.size();

  // One time order over the measurement kinds (the graph stream needs it);
  // at equal times ranges first, then TDoA, then ultrasonic (stable).
  std::vector<FeedItem> items;
  items.reserve(ranges.size() + tdoa.size() + ultrasonic.size());
  for (std::size_t k = 0; k < ranges.size(); ++k) items.push_back({ranges[k].t_ns, Measurement::Kind::kRange, k});
  for (std::size_t k = 0; k < tdoa.size(); ++k) items.push_back({tdoa[k].t_ns, Measurement::Kind::kTdoa, k});
  for (std::size_t k = 0; k < ultrasonic.size(); ++k) {
    items.push_back({ultrasonic[k].t_ns, Measurement::Kind::kUltrasonic, k});
  }
  std::stable_sort(items.begin(), items.end(), [](const FeedItem& a, const FeedItem& b) { return a.t_ns < b.t_ns; });
  auto feed = [&](const FeedItem& item) {
    switch (item.kind) {
      case Measurement::Kind::kRange: localizer.addRange(ranges[item.index]); break;
      case Measurement::Kind::kTdoa: localizer.addTdoa(tdoa[item.index]); break;
      case Measurement::Kind::kUltrasonic: localizer.addUltrasonic(ultrasonic[item.index]); break;
    }
  };

  const std::size_t total = rec.imu.size() + items.size();
  const std::size_t progress_every = std::max<std::size_t>(1, total / 100);
  const auto wall_start = std::chrono::steady_clock::now();
  std::size_t i = 0, r = 0;
  const std::int64_t t0_ns = items.empty() ? rec.imu.front().t_ns : std::min(rec.imu.front().t_ns, items.front().t_ns);
  std::uint64_t provisional_written = 0;  // sequences start at 1
  while (i < rec.imu.size() || r < items.size()) {
    if (settings.progress && (i + r) % progress_every == 0) {
      settings.progress(static_cast<double>(i + r) / static_cast<double>(total));
    }
    if (r < items.size() && (i >= rec.imu.size() || items[r].t_ns <= rec.imu[i].t_ns)) {
      feed(items[r++]);
    } else {
      localizer.addImu(rec.imu[i++]);
    }
    stats.clear();
    const int updates = localizer.process(&stats);
    if (!localizer.tracking()) {
      if (const auto fix = localizer.provisionalPosition(); fix && fix->sequence != provisional_written) {
        provisional_written = fix->sequence;
        out.position_only.push_back({fix->t_ns, Pose3(Mat3::Identity(), fix->p_w_b)});
        out.published_covariance.push_back({fix->t_ns, fix->p_w_b, fix->cov_p_w, true});
        if (!out.first_position_s) out.first_position_s = static_cast<double>(fix->t_ns - t0_ns) * 1e-9;
      }
      continue;
    }
    if (updates == 0) continue;
    const StateEstimate& s = localizer.latest();
    if (!out.first_full_state_s) out.first_full_state_s = static_cast<double>(s.t_ns - t0_ns) * 1e-9;
    if (!out.first_position_s) out.first_position_s = out.first_full_state_s;
    out.online.push_back({s.t_ns, s.T_w_b});
    if (const auto cov = localizer.latestPoseCovariance()) {
      // Tangent [rot; trans], translation in the body frame (Service::navigationState).
      const Mat3 cov_p_w = s.T_w_b.R * Mat6(*cov).bottomRightCorner<3, 3>() * s.T_w_b.R.transpose();
      out.published_covariance.push_back({s.t_ns, s.T_w_b.p, cov_p_w, false});
    }
    for (const UpdateStats& u : stats) out.updates.push_back({s.t_ns, u});
    localizer.drainSmoothed(out.smoothed);
  }
  localizer.finish();
  localizer.process();
  localizer.drainSmoothed(out.smoothed, true);
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  if (settings.progress) settings.progress(1.0);
  std::sort(out.smoothed.begin(), out.smoothed.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  // What was published, both kinds, in time order (the first full state may
  // be older than the last fix before it: the batch hands over a state inside
  // its window).
  std::vector<RangeImuEstimator::TimedPose> published = out.online;
  published.insert(published.end(), out.position_only.begin(), out.position_only.end());
  std::stable_sort(published.begin(), published.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });

  out.data_s = static_cast<double>(rec.imu.back().t_ns - rec.imu.front().t_ns) * 1e-9;
  out.online_tracked_share = trackedShare(published, rec.imu.front().t_ns, rec.imu.back().t_ns);
  counts.tdoa.deep_nlos = localizer.tdoaRowsGated();
  out.initializations = localizer.initializations();
  out.reinitializations = localizer.reinitializations();
  out.standstill_priors = localizer.standstillPriors();
  out.input_dropped = localizer.inputDropped();
  out.dynamic_covariance = localizer.trackingDynamicCovariance();
  out.last_failure = localizer.lastFailure();
  out.init_status = localizer.initStatus().message;
  out.init_attempts = localizer.initStatus().attempts;
  out.height_band_note = localizer.heightBandNote();
  out.flagged_excess_m = localizer.flaggedExcess();
  out.nlos_gap_db = localizer.nlosGapDb();
  out.flagged_scale_m = localizer.trackingFlaggedScaleM();
  out.height_band_in_use = localizer.params().graph.height_band.enabled;
  // Judged with the noise the tracker used (its flagged scale follows the ranging rate).
  const RangeModel range_model(params.graph.range_loss, localizer.trackingRangeNoise());
  NlosClassificationOptions classification;
  classification.tag_lever_arms = params.graph.tag_lever_arms;
  out.nlos = classifyRanges(ranges, out.smoothed, uwbAnchorsById(rec.anchors), params.graph.p_b_tag, range_model,
                            params.graph.range_noise.sigma_m, classification);
  std::stable_sort(out.published_covariance.begin(), out.published_covariance.end(),
                   [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  if (!rec.groundtruth.empty()) {
    out.ape_online = positionErrorAgainst(published, rec.groundtruth);
    out.ape_smoothed = positionErrorAgainst(out.smoothed, rec.groundtruth);
    out.covariance_online = covarianceConsistency(out.published_covariance, rec.groundtruth, kDefaultAssociationMaxDtNs);
    std::vector<TimedPositionCovariance> fixes;
    std::copy_if(out.published_covariance.begin(), out.published_covariance.end(), std::back_inserter(fixes),
                 [](const TimedPositionCovariance& c) { return c.position_only; });
    out.covariance_position_only = covarianceConsistency(fixes, rec.groundtruth, kDefaultAssociationMaxDtNs);
  }
  return out;
}

}  // namespace rilo
