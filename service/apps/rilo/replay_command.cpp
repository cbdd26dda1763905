#include "replay_command.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "estimation/pipeline/localizer.h"
#include "estimation/pipeline/trajectory_error.h"
#include "hal/recording/recording_reader.h"

namespace rilo::tool {

namespace {

/// Estimated positions paired with the ground truth nearest in time (within
/// 50 ms; no alignment: the anchors fix the frame).
PositionErrorStats positionError(const std::vector<RangeImuEstimator::TimedPose>& poses,
                                 const std::vector<GroundTruthPose>& truth) {
  std::vector<Vec3> p_est, p_true;
  for (const auto& p : poses) {
    auto it = std::lower_bound(truth.begin(), truth.end(), p.t_ns,
                               [](const GroundTruthPose& g, std::int64_t t) { return g.t_ns < t; });
    if (it != truth.begin() && (it == truth.end() || std::abs(std::prev(it)->t_ns - p.t_ns) < std::abs(it->t_ns - p.t_ns))) {
      --it;
    }
    if (it == truth.end() || std::abs(it->t_ns - p.t_ns) > 50'000'000) continue;
    p_est.push_back(p.T_w_b.p);
    p_true.push_back(it->p_w_b);
  }
  return positionErrorStats(p_est, p_true);
}

void writeTum(const std::filesystem::path& file, const std::vector<RangeImuEstimator::TimedPose>& poses) {
  std::ofstream out(file);
  out << "# t_s x y z qx qy qz qw (TUM; world frame of the anchors)\n";
  char line[256];
  for (const auto& p : poses) {
    const Eigen::Quaterniond q(p.T_w_b.R);
    std::snprintf(line, sizeof line, "%.9f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", static_cast<double>(p.t_ns) * 1e-9,
                  p.T_w_b.p.x(), p.T_w_b.p.y(), p.T_w_b.p.z(), q.x(), q.y(), q.z(), q.w());
    out << line;
  }
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

std::string statsJson(const PositionErrorStats& s) {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "{\"poses\": %zu, \"mean_m\": %.4f, \"median_m\": %.4f, \"rmse_m\": %.4f, \"max_m\": %.4f, "
                "\"horizontal_mean_m\": %.4f, \"vertical_mean_m\": %.4f}",
                s.ape_3d.count, s.ape_3d.mean, s.ape_3d.median, s.ape_3d.rmse, s.ape_3d.max, s.ape_horizontal.mean,
                s.ape_vertical.mean);
  return buf;
}

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

int runReplay(const ReplayOptions& o) {
  const Recording rec = readRecording(o.recording);
  if (rec.imu.empty() || rec.ranges.empty()) throw std::runtime_error(o.recording + ": needs imu.csv and range.csv samples");
  std::vector<Vec3> anchors;
  for (const Anchor& a : rec.anchors) {
    if (a.kind != AnchorKind::kUwb) continue;
    if (anchors.size() <= a.id) anchors.resize(a.id + 1, Vec3(1e6, 1e6, 1e6));
    anchors[a.id] = a.p_w_anchor;
  }
  LocalizerParams lp;
  lp.graph.imu = imuParamsFrom(rec.meta);
  lp.graph.p_b_tag = rec.meta.uwb_lever_arm_m;
  lp.graph.range_loss = o.noise;
  lp.smoother.method = smootherMethodFromName(o.smoother);
  lp.smoother.lag_s = o.lag_s;
  Localizer localizer(anchors, lp);

  std::filesystem::create_directories(o.out);
  std::ofstream timing(std::filesystem::path(o.out) / "timing.csv");
  timing << "t_s,update_ms,cliques_reeliminated,variables_relinearized,tries,accepted,lambda\n";
  std::vector<RangeImuEstimator::TimedPose> online, smoothed;
  std::vector<UpdateStats> stats;
  std::vector<double> update_ms;
  const double min_range_dt_ns = o.range_hz > 0.0 ? 1e9 / o.range_hz : 0.0;
  std::int64_t last_kept_range_ns = std::numeric_limits<std::int64_t>::min() / 2;
  std::size_t kept_ranges = 0;
  const auto wall_start = std::chrono::steady_clock::now();
  std::size_t i = 0, r = 0;
  while (i < rec.imu.size() || r < rec.ranges.size()) {
    if (r < rec.ranges.size() && (i >= rec.imu.size() || rec.ranges[r].t_ns <= rec.imu[i].t_ns)) {
      const RangeSample& range = rec.ranges[r++];
      if (static_cast<double>(range.t_ns - last_kept_range_ns) < min_range_dt_ns) continue;  // --range-hz thinning
      last_kept_range_ns = range.t_ns;
      ++kept_ranges;
      localizer.addRange(range);
    } else {
      localizer.addImu(rec.imu[i++]);
    }
    stats.clear();
    if (localizer.process(&stats) == 0 || !localizer.tracking()) continue;
    const StateEstimate& s = localizer.latest();
    online.push_back({s.t_ns, s.T_w_b});
    for (const UpdateStats& u : stats) {
      update_ms.push_back(u.time_s * 1e3);
      timing << static_cast<double>(s.t_ns) * 1e-9 << ',' << u.time_s * 1e3 << ',' << u.cliques_reeliminated << ','
             << u.variables_relinearized << ',' << u.step_tries << ',' << (u.step_accepted ? 1 : 0) << ',' << u.lambda << '\n';
    }
    localizer.drainSmoothed(smoothed);
  }
  localizer.finish();
  localizer.process();
  localizer.drainSmoothed(smoothed, true);
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  std::sort(smoothed.begin(), smoothed.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });

  writeTum(std::filesystem::path(o.out) / "online.tum", online);
  writeTum(std::filesystem::path(o.out) / "smoothed.tum", smoothed);
  const double data_s = static_cast<double>(rec.imu.back().t_ns - rec.imu.front().t_ns) * 1e-9;
  std::vector<double> sorted = update_ms;
  std::sort(sorted.begin(), sorted.end());
  double mean_ms = 0.0;
  for (double x : sorted) mean_ms += x / static_cast<double>(std::max<std::size_t>(1, sorted.size()));
  const double p99_ms = sorted.empty() ? 0.0 : sorted[static_cast<std::size_t>(0.99 * static_cast<double>(sorted.size() - 1))];
  const double max_ms = sorted.empty() ? 0.0 : sorted.back();

  std::ofstream summary(std::filesystem::path(o.out) / "summary.json");
  summary << "{\n  \"recording\": \"" << o.recording << "\",\n  \"smoother\": \"" << o.smoother << "\",\n  \"noise\": \""
          << o.noise << "\",\n  \"ranges_used\": " << kept_ranges << ",\n  \"updates\": " << update_ms.size()
          << ",\n  \"update_ms\": {\"mean\": " << mean_ms << ", \"p99\": " << p99_ms << ", \"max\": " << max_ms
          << "},\n  \"realtime_factor\": " << (wall_s > 0.0 ? data_s / wall_s : 0.0)
          << ",\n  \"initializations\": " << localizer.initializations()
          << ",\n  \"reinitializations\": " << localizer.reinitializations();
  if (!rec.groundtruth.empty()) {
    summary << ",\n  \"ape_online\": " << statsJson(positionError(online, rec.groundtruth))
            << ",\n  \"ape_smoothed\": " << statsJson(positionError(smoothed, rec.groundtruth));
  }
  summary << "\n}\n";
  if (!summary) throw std::runtime_error("cannot write " + o.out + "/summary.json");

  std::printf("rilo replay: %s with %s/%s: %zu updates, mean %.2f ms, max %.2f ms, %.0fx real time, %llu re-initializations\n",
              o.recording.c_str(), o.smoother.c_str(), o.noise.c_str(), update_ms.size(), mean_ms, max_ms,
              wall_s > 0.0 ? data_s / wall_s : 0.0, static_cast<unsigned long long>(localizer.reinitializations()));
  if (!rec.groundtruth.empty()) {
    for (const auto& [label, poses] : {std::pair{"online  ", &online}, std::pair{"smoothed", &smoothed}}) {
      const PositionErrorStats e = positionError(*poses, rec.groundtruth);
      std::printf("  APE %s mean %.3f m, median %.3f, rmse %.3f, max %.3f (horizontal %.3f, vertical %.3f)\n", label,
                  e.ape_3d.mean, e.ape_3d.median, e.ape_3d.rmse, e.ape_3d.max, e.ape_horizontal.mean, e.ape_vertical.mean);
    }
  }
  std::printf("  wrote %s/{online.tum,smoothed.tum,timing.csv,summary.json}\n", o.out.c_str());
  return 0;
}

void addReplayCommand(CLI::App& app) {
  auto options = std::make_shared<ReplayOptions>();
  CLI::App* cmd = app.add_subcommand("replay", "Run the online pipeline over a recording (as fast as possible) and write its trajectories and timing");
  cmd->add_option("REC", options->recording, "Recording folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", options->out, "Output folder")->required();
  cmd->add_option("--smoother", options->smoother, "Incremental smoother")
      ->capture_default_str()->check(CLI::IsMember({"d-isam2", "isam2", "dogleg"}));
  cmd->add_option("--noise", options->noise, "Range noise model")
      ->capture_default_str()->check(CLI::IsMember({"gaussian", "huber", "cauchy", "asymmetric"}));
  cmd->add_option("--range-hz", options->range_hz, "Thin ranges to this total rate (Hz; 0 keeps all)")
      ->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  cmd->add_option("--lag", options->lag_s, "Fixed lag of the smoother (s)")->capture_default_str()->check(CLI::Range(0.5, 600.0));
  cmd->callback([options] {
    int code = 1;
    try {
      code = runReplay(*options);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "rilo replay: %s\n", e.what());
    }
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
