#include "evaluation/tdoa_report.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "sim/office_recording.h"

namespace rilo {
namespace {

bool sameReception(double a, double b) { return std::abs(a - b) <= 1e-12; }

TdoaRun runOne(const Recording& rec, const TdoaRunSpec& spec, const TdoaReportOptions& o) {
  TdoaRun run;
  run.spec = spec;
  run.has_truth = !rec.groundtruth.empty();
  try {
    ReplaySettings s;
    s.smoother = spec.estimator;
    s.lag_s = o.lag_s;
    s.measurements = o.measurements;
    s.reception = spec.reception;
    s.reception_seed = o.reception_seed;
    s.dynamic_covariance = o.dynamic_covariance;
    ReplayResult r = replayRecording(rec, s);
    if (r.ape_online) run.ape_online = *r.ape_online;
    if (r.ape_smoothed) run.ape_smoothed = *r.ape_smoothed;
    std::vector<double> ms;
    ms.reserve(r.updates.size());
    for (const ReplayUpdate& u : r.updates) ms.push_back(u.stats.time_s * 1e3);
    std::sort(ms.begin(), ms.end());
    run.updates = ms.size();
    if (!ms.empty()) {
      double sum = 0.0;
      for (double x : ms) sum += x;
      run.update_mean_ms = sum / static_cast<double>(ms.size());
      // Nearest rank: the smallest time at or above 99 % of the updates.
      const auto rank = static_cast<std::size_t>(std::ceil(0.99 * static_cast<double>(ms.size())));
      run.update_p99_ms = ms[std::max<std::size_t>(rank, 1) - 1];
      run.update_max_ms = ms.back();
    }
    run.initializations = r.initializations;
    run.reinitializations = r.reinitializations;
    run.last_failure = r.last_failure.empty() && r.initializations == 0 ? "never initialized: " + r.init_status
                                                                          : r.last_failure;
    run.measurements = r.measurements;
    run.data_s = r.data_s;
    run.tracked_share = r.online_tracked_share;
    run.wall_s = r.wall_s;
  } catch (const std::exception& e) {
    run.threw = true;
    run.error = e.what();
    if (run.error.empty()) run.error = "exception without a message";
  } catch (...) {
    run.threw = true;
    run.error = "unknown exception";
  }
  return run;
}

}  // namespace

void TdoaReportOptions::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("report --system tdoa: " + what); };
  if (estimators.empty()) fail("estimators must not be empty");
  const std::vector<std::string>& names = estimatorNames();
  for (const std::string& e : estimators) {
    if (std::find(names.begin(), names.end(), e) == names.end()) fail("unknown estimator '" + e + "'");
    if (std::count(estimators.begin(), estimators.end(), e) > 1) fail("estimators lists '" + e + "' twice");
  }
  if (receptions.empty()) fail("receptions must not be empty");
  for (std::size_t i = 0; i < receptions.size(); ++i) {
    if (!(receptions[i] > 0.0 && receptions[i] <= 1.0)) fail("receptions must be in (0, 1]");
    for (std::size_t j = i + 1; j < receptions.size(); ++j) {
      if (sameReception(receptions[i], receptions[j])) fail("receptions lists a value twice");
    }
  }
  if (!(measurements.range || measurements.tdoa || measurements.ultrasonic)) fail("no measurement kind selected");
  if (!(lag_s > 0.0) || !std::isfinite(lag_s)) fail("lag_s must be finite and > 0");
  if (!(fail_mean_m > 0.0)) fail("fail_mean_m must be > 0");
  if (jobs < 1 || jobs > 256) fail("jobs must be in [1, 256]");
}

bool TdoaRun::failed(double fail_mean_m) const {
  if (threw) return true;
  if (!has_truth) return false;
  // As ReportRun::failed: position-only poses are no success.
  return initializations == 0 || ape_online.ape_3d.count == 0 || !(ape_online.ape_3d.mean <= fail_mean_m);
}

const TdoaRun* TdoaReportResults::find(std::size_t recording, const std::string& estimator, double reception) const {
  for (const TdoaRun& r : runs) {
    if (r.spec.recording == recording && r.spec.estimator == estimator && sameReception(r.spec.reception, reception)) {
      return &r;
    }
  }
  return nullptr;
}

std::vector<TdoaRunSpec> planTdoaRuns(const TdoaReportOptions& o, std::size_t recordings) {
  std::vector<TdoaRunSpec> specs;
  for (std::size_t rec = 0; rec < recordings; ++rec) {
    for (const std::string& e : o.estimators) {
      for (double p : o.receptions) specs.push_back({rec, e, p});
    }
  }
  return specs;
}

TdoaReportResults runTdoaReport(const std::vector<ReportRecording>& recordings, const TdoaReportOptions& options) {
  options.validate();
  if (recordings.empty()) throw std::invalid_argument("report --system tdoa: no recordings");
  TdoaReportResults results;
  results.options = options;
  results.options.progress = nullptr;
  const std::vector<TdoaRunSpec> specs = planTdoaRuns(options, recordings.size());
  results.runs.resize(specs.size());
  const auto start = std::chrono::steady_clock::now();
  parallelFor(
      specs.size(), options.jobs,
      [&](std::size_t i) { results.runs[i] = runOne(recordings[specs[i].recording].data, specs[i], options); },
      options.progress);
  results.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return results;
}

std::filesystem::path simulateTdoaReportRecording(std::uint64_t seed, double seconds, const std::filesystem::path& dir,
                                                  sim::OfficePlanKind plan) {
  // The defaults of `rilo sim` (service/apps/rilo/sim_command.h, SimOptions)
  // with --tdoa --keep-twr --ultrasonic.
  sim::OfficeScenarioParams p;
  p.seed = seed;
  p.duration_s = seconds;
  p.range_rate_hz = 40.0;
  p.anchors.count = 8;
  p.channel.nlos_severity = 1.0;
  p.imu_rate_hz = 800.0;
  p.ranges_per_cycle = 4;
  p.packet_loss = 0.05;
  p.walk.start_moving = false;
  p.plan = plan;
  p.tdoa.enabled = true;
  p.tdoa.keep_twr = true;
  p.ultrasonic.enabled = true;
  sim::validate(p);

  sim::ScenarioRecordingOptions ro;
  ro.name = dir.filename().empty() ? dir.parent_path().filename().string() : dir.filename().string();
  char description[320];
  std::snprintf(description, sizeof(description),
                "rilo report --system tdoa: %s plan, seed %llu, %d anchors, %.1f min walk; TDoA %.1f Hz rounds, "
                "packet reception %.2f, sigma %.3f m; SS-TWR kept (%.1f Hz); ultrasonic %d beacons at %.1f Hz",
                plan == sim::OfficePlanKind::kHall ? "hall" : plan == sim::OfficePlanKind::kRandom ? "random office" : "default office",
                static_cast<unsigned long long>(seed), p.anchors.count, seconds / 60.0, p.tdoa.round_rate_hz,
                p.tdoa.packet_reception, p.tdoa.sigma_m, p.range_rate_hz, p.ultrasonic.beacons, p.ultrasonic.ping_rate_hz);
  ro.description = description;
  ro.truth_rate_hz = 200.0;
  ro.writer.overwrite = true;
  std::filesystem::create_directories(dir);
  sim::writeOfficeRecording(p, dir, ro);
  return dir;
}

double improvementPercent(double proposed, double baseline) {
  if (!std::isfinite(proposed) || !std::isfinite(baseline) || baseline == 0.0) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  return (baseline - proposed) / baseline * 100.0;
}

}  // namespace rilo
