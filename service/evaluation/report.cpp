#include "evaluation/report.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

#include "evaluation/replay_run.h"
#include "hal/recording/recording_reader.h"
#include "sim/office_recording.h"

namespace rilo {
namespace {

constexpr std::int64_t kErrorMaxDtNs = 50'000'000;

bool sameRate(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b)); }

bool isKnownSmoother(const std::string& s) {
  const std::vector<std::string>& names = estimatorNames();
  return std::find(names.begin(), names.end(), s) != names.end();
}
bool isKnownNoise(const std::string& n) {
  return n == "asymmetric" || n == "gaussian" || n == "huber" || n == "cauchy" || n == "asymmetric-half-cauchy";
}

template <typename T>
void requireUnique(const std::vector<T>& values, const char* option) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    for (std::size_t j = i + 1; j < values.size(); ++j) {
      if (values[i] == values[j]) throw std::invalid_argument(std::string("report: ") + option + " lists a value twice");
    }
  }
}

ReportRun runOne(const Recording& rec, const ReportRunSpec& spec, const ReportOptions& options) {
  ReportRun run;
  run.spec = spec;
  run.has_truth = !rec.groundtruth.empty();
  try {
    ReplaySettings settings;
    settings.smoother = spec.smoother;
    settings.noise = spec.noise;
    settings.range_hz = spec.all_ranges ? 0.0 : spec.rate_hz;
    settings.lag_s = options.lag_s;
    ReplayResult r = replayRecording(rec, settings);
    if (r.ape_online) run.ape_online = *r.ape_online;
    if (r.ape_smoothed) run.ape_smoothed = *r.ape_smoothed;
    run.updates = r.updates.size();
    for (const ReplayUpdate& u : r.updates) {
      const double ms = u.stats.time_s * 1e3;
      run.update_sum_ms += ms;
      run.update_max_ms = std::max(run.update_max_ms, ms);
    }
    run.update_mean_ms = run.updates ? run.update_sum_ms / static_cast<double>(run.updates) : 0.0;
    run.data_s = r.data_s;
    run.wall_s = r.wall_s;
    run.realtime_factor = r.realtimeFactor();
    run.ranges_used = r.ranges_used;
    run.initializations = r.initializations;
    run.reinitializations = r.reinitializations;
    run.last_failure = r.last_failure;
    if (spec.keep_trajectory) run.online = std::move(r.online);
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

double ReportRecording::durationS() const {
  if (data.imu.size() < 2) return 0.0;
  return static_cast<double>(data.imu.back().t_ns - data.imu.front().t_ns) * 1e-9;
}

double ReportRecording::rangeRateHz() const {
  const double d = durationS();
  return d > 0.0 ? static_cast<double>(data.ranges.size()) / d : 0.0;
}

std::size_t ReportRecording::uwbAnchors() const {
  return static_cast<std::size_t>(
      std::count_if(data.anchors.begin(), data.anchors.end(), [](const Anchor& a) { return a.kind == AnchorKind::kUwb; }));
}

ReportRecording loadReportRecording(const std::filesystem::path& dir) {
  ReportRecording r;
  r.path = dir.string();
  r.label = dir.filename().empty() ? dir.parent_path().filename().string() : dir.filename().string();
  if (r.label.empty()) r.label = "recording";
  r.data = readRecording(dir);
  return r;
}

void makeLabelsUnique(std::vector<ReportRecording>& recordings) {
  std::set<std::string> used;
  for (ReportRecording& r : recordings) {
    std::string label = r.label;
    for (int k = 2; used.count(label) != 0; ++k) label = r.label + "-" + std::to_string(k);
    r.label = label;
    used.insert(label);
  }
}

std::filesystem::path simulateReportRecording(std::uint64_t seed, double seconds, const std::filesystem::path& dir,
                                              sim::OfficePlanKind plan) {
  // The defaults of `rilo sim` (service/apps/rilo/sim_command.h, SimOptions).
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
  sim::validate(p);

  sim::ScenarioRecordingOptions ro;
  ro.name = dir.filename().empty() ? dir.parent_path().filename().string() : dir.filename().string();
  char description[256];
  std::snprintf(description, sizeof(description),
                "rilo report: %s plan, seed %llu, %d anchors, %.1f min walk, ranging %.1f Hz (%d per "
                "cycle), packet loss %.2f, NLOS severity %.2f",
                plan == sim::OfficePlanKind::kHall ? "hall" : plan == sim::OfficePlanKind::kRandom ? "random office" : "default office",
                static_cast<unsigned long long>(seed), p.anchors.count, seconds / 60.0, p.range_rate_hz, p.ranges_per_cycle,
                p.packet_loss, p.channel.nlos_severity);
  ro.description = description;
  ro.truth_rate_hz = 200.0;
  ro.writer.overwrite = true;
  std::filesystem::create_directories(dir);
  sim::writeOfficeRecording(p, dir, ro);
  return dir;
}

void ReportOptions::makeQuick() {
  rates_hz = {1.0, 40.0};
  smoothers = {"d-isam2", "isam2"};
}

void ReportOptions::validate() const {
  if (smoothers.empty()) throw std::invalid_argument("report: smoothers must not be empty");
  if (noises.empty()) throw std::invalid_argument("report: noises must not be empty");
  if (rates_hz.empty()) throw std::invalid_argument("report: rates must not be empty");
  for (const std::string& s : smoothers) {
    if (!isKnownSmoother(s)) {
      throw std::invalid_argument("report: smoothers: unknown smoother '" + s + "' (d-isam2, isam2, dogleg, sliding-window, ekf)");
    }
  }
  for (const std::string& n : noises) {
    if (!isKnownNoise(n)) {
      throw std::invalid_argument("report: noises: unknown noise model '" + n +
                                  "' (asymmetric, gaussian, huber, cauchy, asymmetric-half-cauchy)");
    }
  }
  requireUnique(smoothers, "smoothers");
  requireUnique(noises, "noises");
  if (!(full_rate_hz > 0.0) || !std::isfinite(full_rate_hz)) {
    throw std::invalid_argument("report: full_rate_hz must be finite and > 0");
  }
  if (!(low_rate_hz > 0.0 && low_rate_hz <= full_rate_hz)) {
    throw std::invalid_argument("report: low_rate_hz must be in (0, full_rate_hz]");
  }
  for (double r : rates_hz) {
    if (!(r > 0.0 && r <= full_rate_hz)) {
      throw std::invalid_argument("report: rates must be in (0, " + std::to_string(full_rate_hz) +
                                  "] Hz (the full rate replays every range)");
    }
  }
  for (std::size_t i = 0; i < rates_hz.size(); ++i) {
    for (std::size_t j = i + 1; j < rates_hz.size(); ++j) {
      if (sameRate(rates_hz[i], rates_hz[j])) throw std::invalid_argument("report: rates lists a rate twice");
    }
  }
  if (!(fail_mean_m > 0.0)) throw std::invalid_argument("report: fail_mean_m must be > 0");
  if (!(lag_s > 0.0) || !std::isfinite(lag_s)) throw std::invalid_argument("report: lag_s must be finite and > 0");
  if (jobs < 1 || jobs > 256) throw std::invalid_argument("report: jobs must be in [1, 256]");
}

std::string ReportOptions::headlineSmoother() const {
  if (smoothers.empty() || std::find(smoothers.begin(), smoothers.end(), "d-isam2") != smoothers.end()) {
    return "d-isam2";
  }
  return smoothers.front();
}

std::string ReportOptions::headlineNoise() const {
  if (noises.empty() || std::find(noises.begin(), noises.end(), "asymmetric") != noises.end()) return "asymmetric";
  return noises.front();
}

bool ReportRun::failed(double fail_mean_m) const {
  if (threw) return true;
  if (!has_truth) return false;
  // Position-only poses (published while initializing) do not make a run
  // that never reached the full state a success.
  return initializations == 0 || ape_online.ape_3d.count == 0 || !(ape_online.ape_3d.mean <= fail_mean_m);
}

const ReportRun* ReportResults::find(std::size_t recording, const std::string& smoother, const std::string& noise,
                                     double rate_hz) const {
  for (const ReportRun& r : runs) {
    if (r.spec.recording == recording && r.spec.smoother == smoother && r.spec.noise == noise &&
        sameRate(r.spec.rate_hz, rate_hz)) {
      return &r;
    }
  }
  return nullptr;
}

std::vector<ReportRunSpec> planReportRuns(const ReportOptions& o, std::size_t recordings) {
  const std::string head_smoother = o.headlineSmoother();
  const std::string head_noise = o.headlineNoise();
  // Fig. 7 rates plus the Table I and Table II rates, ascending.
  std::vector<double> rates = o.rates_hz;
  for (double r : {o.low_rate_hz, o.full_rate_hz}) {
    if (std::none_of(rates.begin(), rates.end(), [r](double x) { return sameRate(x, r); })) rates.push_back(r);
  }
  std::sort(rates.begin(), rates.end());

  std::vector<ReportRunSpec> specs;
  for (std::size_t rec = 0; rec < recordings; ++rec) {
    const auto add = [&](const std::string& smoother, const std::string& noise, double rate) {
      for (const ReportRunSpec& s : specs) {
        if (s.recording == rec && s.smoother == smoother && s.noise == noise && sameRate(s.rate_hz, rate)) return;
      }
      ReportRunSpec s;
      s.recording = rec;
      s.smoother = smoother;
      s.noise = noise;
      s.rate_hz = rate;
      s.all_ranges = rate >= o.full_rate_hz;
      s.keep_trajectory = s.all_ranges && smoother == head_smoother && noise == head_noise;
      specs.push_back(std::move(s));
    };
    for (const std::string& smoother : o.smoothers) {  // Table I (and III)
      for (const std::string& noise : o.noises) add(smoother, noise, o.full_rate_hz);
    }
    for (double rate : rates) {  // Fig. 7 and Table II
      for (const std::string& noise : o.noises) add(head_smoother, noise, rate);
    }
  }
  return specs;
}

void parallelFor(std::size_t n, int jobs, const std::function<void(std::size_t)>& fn,
                 const std::function<void(std::size_t done, std::size_t total)>& progress) {
  if (progress) progress(0, n);
  if (n == 0) return;
  std::mutex progress_mutex;
  std::size_t done = 0;
  const std::size_t threads = std::min<std::size_t>(n, static_cast<std::size_t>(std::max(jobs, 1)));
  std::atomic<std::size_t> next{0};
  std::exception_ptr first_error;
  std::mutex error_mutex;
  const auto worker = [&] {
    for (;;) {
      const std::size_t i = next.fetch_add(1);
      if (i >= n) return;
      try {
        fn(i);
        if (progress) {
          std::lock_guard<std::mutex> lock(progress_mutex);
          progress(++done, n);
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!first_error) first_error = std::current_exception();
        next.store(n);  // stop handing out work
      }
    }
  };
  if (threads == 1) {
    worker();
  } else {
    std::vector<std::thread> pool;
    pool.reserve(threads);
    for (std::size_t t = 0; t < threads; ++t) pool.emplace_back(worker);
    for (std::thread& t : pool) t.join();
  }
  if (first_error) std::rethrow_exception(first_error);
}

ReportResults runReport(const std::vector<ReportRecording>& recordings, const ReportOptions& options) {
  options.validate();
  if (recordings.empty()) throw std::invalid_argument("report: no recordings");
  ReportResults results;
  results.options = options;
  results.options.progress = nullptr;
  const std::vector<ReportRunSpec> specs = planReportRuns(options, recordings.size());
  results.runs.resize(specs.size());

  const auto start = std::chrono::steady_clock::now();
  parallelFor(
      specs.size(), options.jobs,
      [&](std::size_t i) { results.runs[i] = runOne(recordings[specs[i].recording].data, specs[i], options); },
      options.progress);
  results.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return results;
}

std::vector<ErrorSample> errorOverTime(const std::vector<RangeImuEstimator::TimedPose>& poses,
                                       const Recording& recording) {
  std::vector<ErrorSample> out;
  const std::vector<GroundTruthPose>& truth = recording.groundtruth;
  if (truth.empty()) return out;
  const std::int64_t t0_ns = recording.imu.empty() ? truth.front().t_ns : recording.imu.front().t_ns;
  out.reserve(poses.size());
  for (const auto& p : poses) {
    auto it = std::lower_bound(truth.begin(), truth.end(), p.t_ns,
                               [](const GroundTruthPose& g, std::int64_t t) { return g.t_ns < t; });
    if (it != truth.begin() &&
        (it == truth.end() || std::abs(std::prev(it)->t_ns - p.t_ns) < std::abs(it->t_ns - p.t_ns))) {
      --it;
    }
    if (it == truth.end() || std::abs(it->t_ns - p.t_ns) > kErrorMaxDtNs) continue;
    const Vec3 d = p.T_w_b.p - it->p_w_b;
    out.push_back({static_cast<double>(p.t_ns - t0_ns) * 1e-9, d.norm(), d.head<2>().norm(), std::abs(d.z())});
  }
  return out;
}

}  // namespace rilo
