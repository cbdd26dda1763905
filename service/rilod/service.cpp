#include "rilod/service.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <ctime>
#include <thread>

#include "hal/bus/clock.h"
#include "estimation/math/so3.h"
#include "runtime/spsc_queue.h"

namespace rilo {

namespace {

std::int64_t sampleTime(const Sample& s) {
  return std::visit([](const auto& v) { return v.t_ns; }, s);
}

}  // namespace

// One source's queues: every sample to the estimator, IMU samples also to the
// publisher. Single producer (the source's thread), single consumer each.
struct Service::SourceLane {
  explicit SourceLane(std::size_t capacity) : samples(capacity), imu(capacity) {}
  SpscQueue<Sample> samples;
  SpscQueue<ImuSample> imu;
  std::atomic<bool> ended{false};
  std::atomic<std::int64_t> last_sample_wall_ns{0};
  // Estimator side: one sample taken out of `samples`, waiting for the merge.
  Sample pending;
  bool has_pending = false;
};

class Service::LaneSink final : public SampleSink {
 public:
  LaneSink(Service& service, SourceLane& lane) : service_(service), lane_(lane) {}
  void push(const Sample& sample) noexcept override {
    lane_.last_sample_wall_ns.store(hal::monotonicNowNs(), std::memory_order_relaxed);
    if (!pushOrWait(lane_.samples, sample)) service_.counters_.queue_overflows.add();
    if (const auto* imu = std::get_if<ImuSample>(&sample)) {
      service_.counters_.imu_samples.add();
      if (!pushOrWait(lane_.imu, *imu)) service_.counters_.queue_overflows.add();
    } else if (std::holds_alternative<RangeSample>(sample)) {
      service_.counters_.range_samples.add();
    } else if (std::holds_alternative<TdoaSample>(sample)) {
      service_.counters_.tdoa_samples.add();
    } else if (std::holds_alternative<UltrasonicSample>(sample)) {
      service_.counters_.ultrasonic_samples.add();
    }
  }
  void fault(const SourceFault& fault) noexcept override {
    service_.counters_.sensor_faults.add();
    if (fault.fatal) service_.source_failed_.store(true);
    try {
      {
        std::lock_guard<std::mutex> lock(service_.stats_mutex_);
        service_.last_fault_ = fault.device + ": " + fault.what;
      }
      if (service_.options_.on_fault) service_.options_.on_fault(fault);
    } catch (...) {
      // Reporting a fault must never take the source down.
    }
  }

 private:
  template <typename T>
  bool pushOrWait(SpscQueue<T>& queue, const T& value) noexcept {
    if (queue.tryPush(value)) return true;
    if (!service_.options_.backpressure) return false;
    while (!service_.stop_sources_.load(std::memory_order_relaxed)) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
      if (queue.tryPush(value)) return true;
    }
    return false;
  }

  Service& service_;
  SourceLane& lane_;
};

Service::Service(ServiceOptions options, std::vector<std::unique_ptr<SampleSource>> sources)
    : options_(std::move(options)),
      sources_(std::move(sources)),
      participant_(options_.participant),
      publisher_(participant_, options_.publisher),
      localizer_(options_.p_w_anchors, options_.localizer),
      predictor_(options_.predictor) {
  if (sources_.empty()) throw std::invalid_argument("Service: no sample source configured");
  if (!(options_.status_period_s > 0.0)) throw std::invalid_argument("Service: status_period_s must be > 0");
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    lanes_.push_back(std::make_unique<SourceLane>(options_.queue_capacity));
  }
}

Service::~Service() = default;

bool Service::allSourcesDone() const {
  return std::all_of(lanes_.begin(), lanes_.end(), [](const auto& lane) { return lane->ended.load(); });
}

int Service::run(const std::atomic<bool>& stop) {
  std::vector<std::thread> source_threads;
  std::vector<std::unique_ptr<LaneSink>> sinks;
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    sinks.push_back(std::make_unique<LaneSink>(*this, *lanes_[i]));
    source_threads.emplace_back([this, i, sink = sinks.back().get()] {
      try {
        const SourceEnd end = sources_[i]->run(*sink, stop_sources_);
        if (end == SourceEnd::kFailed) source_failed_.store(true);
      } catch (const std::exception& e) {
        sink->fault(SourceFault{hal::monotonicNowNs(), sources_[i]->describe(), e.what(), true});
      }
      lanes_[i]->ended.store(true, std::memory_order_release);
    });
    if (options_.on_thread_start) options_.on_thread_start("source " + std::to_string(i), source_threads.back());
  }
  std::thread estimator([this] { estimatorLoop(); });
  std::thread publisher([this] { publisherLoop(); });
  if (options_.on_thread_start) {
    options_.on_thread_start("estimator", estimator);
    options_.on_thread_start("publisher", publisher);
  }

  const auto period_ns = static_cast<std::int64_t>(options_.status_period_s * 1e9);
  std::int64_t next_status_ns = hal::monotonicNowNs();
  while (!stop.load() && !estimator_done_.load()) {
    const std::int64_t now = hal::monotonicNowNs();
    if (now >= next_status_ns) {
      publishStatus(now);
      next_status_ns = now + period_ns;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  stop_sources_.store(true);
  for (std::thread& t : source_threads) t.join();
  stop_threads_.store(true);
  estimator.join();
  publisher.join();
  publishStatus(hal::monotonicNowNs());
  return source_failed_.load() ? 1 : 0;
}

void Service::estimatorLoop() {
  std::vector<UpdateStats> stats;
  std::vector<TimedPose> smoothed;  // drained and dropped, see below
  const auto silence_ns = static_cast<std::int64_t>(options_.sensor_silence_s * 1e9);
  std::vector<bool> silent(lanes_.size(), false);
  int init_attempts_seen = 0;
  for (;;) {
    const std::int64_t now = hal::monotonicNowNs();
    estimator_beat_.beat(now);
    // Take the oldest pending sample across sources. A live source with
    // nothing pending holds the merge back (it may still deliver an older
    // sample), unless it has been quiet for a while.
    bool all_ready = true;
    int oldest = -1;
    for (std::size_t i = 0; i < lanes_.size(); ++i) {
      SourceLane& lane = *lanes_[i];
      if (!lane.has_pending) lane.has_pending = lane.samples.tryPop(lane.pending);
      if (lane.has_pending) {
        if (oldest < 0 || sampleTime(lane.pending) < sampleTime(lanes_[static_cast<std::size_t>(oldest)]->pending)) {
          oldest = static_cast<int>(i);
        }
        silent[i] = false;
        continue;
      }
      const std::int64_t last = lane.last_sample_wall_ns.load(std::memory_order_relaxed);
      const bool quiet = lane.ended.load(std::memory_order_acquire) || (last > 0 && now - last > 20'000'000);
      if (!quiet) all_ready = false;
      if (!lane.ended.load() && last > 0 && now - last > silence_ns && !silent[i]) {
        silent[i] = true;
        counters_.sensor_silences.add();
      }
    }
    if (oldest < 0 || !all_ready) {
      if (stop_threads_.load() || (allSourcesDone() && oldest < 0)) break;
      std::this_thread::sleep_for(std::chrono::microseconds(500));
      continue;
    }
    SourceLane& lane = *lanes_[static_cast<std::size_t>(oldest)];
    lane.has_pending = false;
    // Before the sample: adding one can already end tracking (IMU silence).
    const bool was_tracking = localizer_.tracking();
    const std::uint64_t reinit_before = localizer_.reinitializations();
    if (const auto* imu = std::get_if<ImuSample>(&lane.pending)) {
      localizer_.addImu(*imu);
    } else if (const auto* range = std::get_if<RangeSample>(&lane.pending)) {
      localizer_.addRange(*range);
    } else if (const auto* tdoa = std::get_if<TdoaSample>(&lane.pending)) {
      // Anchors and beacons the configuration does not know are skipped here:
      // the estimator would refuse them and end tracking.
      if (tdoa->anchor_a >= options_.p_w_anchors.size() || tdoa->anchor_b >= options_.p_w_anchors.size()) continue;
      localizer_.addTdoa(*tdoa);
    } else if (const auto* us = std::get_if<UltrasonicSample>(&lane.pending)) {
      if (us->anchor_id >= options_.localizer.graph.p_w_ultrasonic.size()) continue;
      localizer_.addUltrasonic(*us);
    } else {
      continue;
    }
    stats.clear();
    const auto t_start = std::chrono::steady_clock::now();
    const int updates = localizer_.process(&stats);
    // The smoothed states that left the smoother's window are not published
    // (the smoothed topic carries the newest state): take them so the
    // estimator's hand-back buffer stays bounded over hours.
    smoothed.clear();
    localizer_.drainSmoothed(smoothed);
    const double elapsed_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_start).count();
    if (localizer_.reinitializations() != reinit_before) {
      counters_.reinitializations.add(localizer_.reinitializations() - reinit_before);
      if (options_.on_event) options_.on_event("tracking lost: " + localizer_.lastFailure() + "; re-initializing");
    }
    if (!was_tracking && localizer_.tracking() && options_.on_event) {
      options_.on_event("initialized: " + localizer_.initStatus().message);
    }
    if (!localizer_.tracking() && localizer_.initStatus().attempts != init_attempts_seen) {
      init_attempts_seen = localizer_.initStatus().attempts;
      if (options_.on_event) options_.on_event("initialization attempt " + std::to_string(init_attempts_seen) + ": " +
                                               localizer_.initStatus().message);
    }
    tracking_.store(localizer_.tracking() ? TrackingState::kTracking : TrackingState::kInitializing);
    if (updates == 0 || !localizer_.tracking()) continue;
    const NavigationState state = navigationState();
    smoothed_.write(state);
    (void)publisher_.publishPose(state);  // failures show in the status counters of the subscriber side
    std::lock_guard<std::mutex> lock(stats_mutex_);
    for (const UpdateStats& s : stats) {
      const double ms = s.time_s * 1e3;
      last_update_ms_ = ms;
      sum_update_ms_ += ms;
      max_update_ms_ = std::max(max_update_ms_, ms);
      ++updates_;
      if (ms > options_.late_update_ms) counters_.late_updates.add();
      last_stats_ = s;
    }
    if (elapsed_ms > options_.late_update_ms && stats.empty()) counters_.late_updates.add();
    pose_latency_ms_ = static_cast<double>(now - state.t_ns) * 1e-6;
  }
  // End of data: let the last ranging group through.
  localizer_.finish();
  stats.clear();
  if (localizer_.process(&stats) > 0 && localizer_.tracking()) {
    const NavigationState state = navigationState();
    smoothed_.write(state);
    (void)publisher_.publishPose(state);
  }
  estimator_done_.store(true);
}

NavigationState Service::navigationState() {
  const StateEstimate& s = localizer_.latest();
  NavigationState n;
  n.t_ns = s.t_ns;
  n.q_w_b = Eigen::Quaterniond(s.T_w_b.R);
  n.p_w_b = s.T_w_b.p;
  n.v_w_b = s.v_w;
  n.accel_bias_m_s2 = s.bias.vector().head<3>();
  n.gyro_bias_rad_s = s.bias.vector().tail<3>();
  n.valid = true;
  // Our pose tangent is [rot; trans] with both in the body frame (retract:
  // R Exp(phi), p + R rho); ROS wants (position in world, rotation).
  if (const auto cov = localizer_.latestPoseCovariance()) {
    const Eigen::Matrix<double, 6, 6> c = *cov;
    const Mat3& R = s.T_w_b.R;
    n.pose_covariance.topLeftCorner<3, 3>() = R * c.bottomRightCorner<3, 3>() * R.transpose();
    n.pose_covariance.topRightCorner<3, 3>() = R * c.bottomLeftCorner<3, 3>();
    n.pose_covariance.bottomLeftCorner<3, 3>() = n.pose_covariance.topRightCorner<3, 3>().transpose();
    n.pose_covariance.bottomRightCorner<3, 3>() = c.topLeftCorner<3, 3>();
  }
  // Linear velocity from the smoother; the body rate's uncertainty is the
  // gyro's, which the output predictor fills per sample.
  n.twist_covariance.setIdentity();
  if (const auto cov = localizer_.latestVelocityCovariance()) n.twist_covariance.topLeftCorner<3, 3>() = *cov;
  return n;
}

void Service::publisherLoop() {
  std::uint64_t smoothed_version = 0;
  NavigationState smoothed;
  ImuSample imu;
  while (!stop_threads_.load(std::memory_order_relaxed)) {
    publisher_beat_.beat(hal::monotonicNowNs());
    if (smoothed_.readIfNewer(smoothed, smoothed_version)) predictor_.onSmoothed(smoothed);
    bool any = false;
    for (auto& lane : lanes_) {
      while (lane->imu.tryPop(imu)) {
        any = true;
        const NavigationState& out = predictor_.onImu(imu);
        if (out.valid && publisher_.publishOdometry(out).ok()) counters_.published_odometry.add();
      }
    }
    if (!any) std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

void Service::publishStatus(std::int64_t now_ns) {
  const ServiceStatus previous = status_.read();
  ServiceStatus s = previous;
  s.t_ns = now_ns;
  counters_.fill(s);
  s.state = tracking_.load();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    s.last_update_ms = last_update_ms_;
    s.mean_update_ms = updates_ > 0 ? sum_update_ms_ / static_cast<double>(updates_) : 0.0;
    s.max_update_ms = max_update_ms_;
    s.last_cliques_reeliminated = static_cast<std::uint32_t>(last_stats_.cliques_reeliminated);
    s.last_relinearized = static_cast<std::uint32_t>(last_stats_.variables_relinearized);
    s.last_lambda = last_stats_.lambda;
    s.pose_latency_ms = pose_latency_ms_;
    std::memset(s.last_fault.data(), 0, s.last_fault.size());
    std::strncpy(s.last_fault.data(), last_fault_.c_str(), s.last_fault.size() - 1);
  }
  // Tracking through faults in the last period: degraded. Initializing after
  // having tracked: lost (re-initializing).
  const bool trouble = s.sensor_faults > previous.sensor_faults || s.queue_overflows > previous.queue_overflows ||
                       s.sensor_silences > previous.sensor_silences || s.late_updates > previous.late_updates;
  if (s.state == TrackingState::kTracking && trouble) s.state = TrackingState::kDegraded;
  if (s.state == TrackingState::kInitializing && s.reinitializations > 0) s.state = TrackingState::kLost;
  status_.write(s);
  (void)publisher_.publishStatus(s);
  if (options_.on_status) options_.on_status(s);
}

}  // namespace rilo
