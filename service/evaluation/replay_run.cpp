#include "evaluation/replay_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
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

}  // namespace

LocalizerParams localizerParamsFor(const Recording& rec, const ReplaySettings& s) {
  LocalizerParams lp;
  lp.graph.imu = imuParamsFrom(rec.meta);
  lp.graph.p_b_tag = rec.meta.uwb_lever_arm_m;
  lp.graph.range_loss = s.noise;
  if (s.range_sigma_m) lp.graph.range_noise.sigma_m = *s.range_sigma_m;
  if (s.nlos_scale_m) lp.graph.range_noise.nlos_scale_m = *s.nlos_scale_m;
  if (s.nlos_weight) lp.graph.range_noise.nlos_weight = *s.nlos_weight;
  if (s.height_band) lp.track_height_band = *s.height_band;
  if (s.floor_z_m) lp.height_band.floor_z_m = *s.floor_z_m;
  if (s.min_height_m) lp.height_band.min_height_m = *s.min_height_m;
  if (s.max_height_m) lp.height_band.max_height_m = *s.max_height_m;
  if (s.vertical_speed_sigma_m_s) lp.vertical_speed_sigma_m_s = *s.vertical_speed_sigma_m_s;
  setEstimatorByName(lp, s.smoother);
  lp.smoother.lag_s = s.lag_s;
  lp.sliding_window.window_s = s.lag_s;
  return lp;
}

ReplayResult replayRecording(const Recording& rec, const ReplaySettings& settings) {
  if (rec.imu.empty() || rec.ranges.empty()) {
    throw std::runtime_error(rec.meta.name + ": needs imu.csv and range.csv samples");
  }
  if (!(settings.range_hz >= 0.0)) throw std::invalid_argument("replay: range_hz must be >= 0");
  const LocalizerParams params = localizerParamsFor(rec, settings);
  Localizer localizer(uwbAnchorsById(rec.anchors), params);

  ReplayResult out;
  std::vector<UpdateStats> stats;
  RangeThinningOptions thinning;
  thinning.rate_hz = settings.range_hz;
  thinning.mode = settings.thinning;
  const std::vector<RangeSample> ranges = thinRanges(rec.ranges, thinning);
  out.ranges_used = ranges.size();
  const std::size_t total = rec.imu.size() + ranges.size();
  const std::size_t progress_every = std::max<std::size_t>(1, total / 100);
  const auto wall_start = std::chrono::steady_clock::now();
  std::size_t i = 0, r = 0;
  while (i < rec.imu.size() || r < ranges.size()) {
    if (settings.progress && (i + r) % progress_every == 0) {
      settings.progress(static_cast<double>(i + r) / static_cast<double>(total));
    }
    if (r < ranges.size() && (i >= rec.imu.size() || ranges[r].t_ns <= rec.imu[i].t_ns)) {
      localizer.addRange(ranges[r++]);
    } else {
      localizer.addImu(rec.imu[i++]);
    }
    stats.clear();
    if (localizer.process(&stats) == 0 || !localizer.tracking()) continue;
    const StateEstimate& s = localizer.latest();
    out.online.push_back({s.t_ns, s.T_w_b});
    for (const UpdateStats& u : stats) out.updates.push_back({s.t_ns, u});
    localizer.drainSmoothed(out.smoothed);
  }
  localizer.finish();
  localizer.process();
  localizer.drainSmoothed(out.smoothed, true);
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  if (settings.progress) settings.progress(1.0);
  std::sort(out.smoothed.begin(), out.smoothed.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });

  out.data_s = static_cast<double>(rec.imu.back().t_ns - rec.imu.front().t_ns) * 1e-9;
  out.initializations = localizer.initializations();
  out.reinitializations = localizer.reinitializations();
  out.last_failure = localizer.lastFailure();
  out.init_status = localizer.initStatus().message;
  out.init_attempts = localizer.initStatus().attempts;
  out.height_band_note = localizer.heightBandNote();
  out.height_band_in_use = localizer.params().graph.height_band.enabled;
  const RobustLossPtr loss = makeRangeLoss(params.graph.range_loss, params.graph.range_noise);
  out.nlos = classifyRanges(ranges, out.smoothed, uwbAnchorsById(rec.anchors), params.graph.p_b_tag, *loss,
                            params.graph.range_noise.sigma_m);
  if (!rec.groundtruth.empty()) {
    out.ape_online = positionErrorAgainst(out.online, rec.groundtruth);
    out.ape_smoothed = positionErrorAgainst(out.smoothed, rec.groundtruth);
  }
  return out;
}

}  // namespace rilo
