#include "rilod/service.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <numbers>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <thread>

#include "hal/bus/clock.h"
#include "math/so3.h"
#include "rilod/sample_screen.h"
#include "runtime/init_worker.h"
#include "runtime/spsc_queue.h"

namespace rilo {

namespace {

void atomicMax(std::atomic<std::int64_t>& target, std::int64_t value) noexcept {
  std::int64_t current = target.load(std::memory_order_relaxed);
  while (value > current && !target.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
}

std::int64_t sampleTime(const Sample& s) {
  return std::visit([](const auto& v) { return v.t_ns; }, s);
}

/// An IMU sample and when the source handed it to the service (CLOCK_MONOTONIC).
struct TimedImu {
  ImuSample sample;
  std::int64_t arrival_ns = 0;
};

}  // namespace

// One source's queues: every sample to the estimator, IMU samples also to the
// publisher. Single producer (the source's thread), single consumer each.
struct Service::SourceLane {
  SourceLane(std::size_t capacity, const InputScreenParams& screen_params)
      : samples(capacity), imu(capacity), screen(screen_params) {}
  SpscQueue<Sample> samples;
  SpscQueue<TimedImu> imu;
  SampleScreen screen;  // the source's thread only
  std::atomic<bool> ended{false};
  std::atomic<bool> carries_imu{false};  // has delivered an IMU sample: the IMU timeout applies
  std::atomic<bool> silent{false};       // quiet beyond its timeout now (estimator writes)
  std::atomic<std::int64_t> last_sample_wall_ns{0};
  Heartbeat beat;  // the source's thread went round: a sample, a fault or an idle wait (the watchdog's view)
  // Estimator side: one sample taken out of `samples`, waiting for the merge.
  Sample pending;
  bool has_pending = false;
};

class Service::LaneSink final : public SampleSink {
 public:
  LaneSink(Service& service, SourceLane& lane) : service_(service), lane_(lane) {}
  void push(const Sample& sample) noexcept override {
    const std::int64_t now = hal::monotonicNowNs();
    lane_.beat.beat(now);
    lane_.last_sample_wall_ns.store(now, std::memory_order_relaxed);
    RuntimeCounters& counters = service_.counters_;
    switch (lane_.screen.check(sample, service_.newest_imu_ns_.load(std::memory_order_relaxed))) {
      case SampleVerdict::kAccept: break;
      case SampleVerdict::kNonFinite: counters.non_finite_samples.add(); return;
      case SampleVerdict::kDuplicate: counters.duplicate_samples.add(); return;
      case SampleVerdict::kOutOfOrder: counters.out_of_order_samples.add(); return;
      case SampleVerdict::kOutOfBounds: counters.out_of_bounds_samples.add(); return;
      case SampleVerdict::kBeyondFullScale: counters.beyond_full_scale_samples.add(); return;
      case SampleVerdict::kFarFuture: counters.far_future_samples.add(); return;
    }
    if (!pushOrWait(lane_.samples, sample)) counters.queue_overflows.add();
    if (const auto* imu = std::get_if<ImuSample>(&sample)) {
      atomicMax(service_.newest_imu_ns_, imu->t_ns);  // the other sources' measurements are judged against it
      if (!lane_.carries_imu.load(std::memory_order_relaxed)) lane_.carries_imu.store(true, std::memory_order_relaxed);
      counters.imu_samples.add();
      if (!pushOrWait(lane_.imu, TimedImu{*imu, now})) counters.queue_overflows.add();
      service_.publisher_wake_.notify();
    } else if (std::holds_alternative<RangeSample>(sample)) {
      counters.range_samples.add();
    } else if (std::holds_alternative<TdoaSample>(sample)) {
      counters.tdoa_samples.add();
    } else if (std::holds_alternative<UltrasonicSample>(sample)) {
      counters.ultrasonic_samples.add();
    }
  }
  void idle() noexcept override { lane_.beat.beat(hal::monotonicNowNs()); }
  void note(const SourceNote& note) noexcept override {
    try {
      if (service_.options_.on_note) service_.options_.on_note(note);
    } catch (...) {
      // Logging must never take the source down.
    }
  }
  void fault(const SourceFault& fault) noexcept override {
    lane_.beat.beat(hal::monotonicNowNs());
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
      lane_.beat.beat(hal::monotonicNowNs());  // waiting on the estimator, whose own beat tells if it is stuck
      if (queue.tryPush(value)) return true;
    }
    return false;
  }

  Service& service_;
  SourceLane& lane_;
};

namespace {

/// The Localizer behind rilod's entrance (sample_screen.h), which holds and
/// confirms stamp jumps per source: it takes a confirmed jump at once instead
/// of holding its samples a second time. Its value and stamp checks stay.
LocalizerParams behindTheEntrance(LocalizerParams p) {
  p.screen.jump_confirmations = 0;
  return p;
}

std::int64_t secondsToNs(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

std::string initPositionText(const Localizer::ProvisionalPosition& fix) {
  char text[128];
  std::snprintf(text, sizeof text, "(%.2f, %.2f, %.2f) m, sigma %.2f m", fix.p_w_b.x(), fix.p_w_b.y(), fix.p_w_b.z(),
                std::sqrt(fix.cov_p_w.trace()));
  return text;
}

std::int64_t checkedTimeoutNs(double s, const char* name) {
  if (!(std::isfinite(s) && s > 0.0)) throw std::invalid_argument(std::string("Service: ") + name + " must be > 0");
  return secondsToNs(s);
}

/// Appends "; <formatted>" (or just the text when empty) to a NUL-terminated
/// fixed buffer, truncating at its end.
template <std::size_t N>
__attribute__((format(printf, 3, 4))) void appendReason(std::array<char, N>& out, std::size_t& used,
                                                        const char* format, ...) {
  if (used + 1 >= N) return;
  if (used > 0) {
    const int n = std::snprintf(out.data() + used, N - used, "; ");
    used = std::min(N - 1, used + static_cast<std::size_t>(std::max(n, 0)));
  }
  va_list args;
  va_start(args, format);
  const int n = std::vsnprintf(out.data() + used, N - used, format, args);
  va_end(args);
  used = std::min(N - 1, used + static_cast<std::size_t>(std::max(n, 0)));
}

/// The count of `field` that increased since `before`, as unsigned long long for printf.
unsigned long long increase(std::uint64_t now, std::uint64_t before) {
  return static_cast<unsigned long long>(now >= before ? now - before : 0);
}

/// The one writer of `high_water` (the queue's consumer, right after a pop)
/// raises it to the fill the pop found: what is left plus the item taken.
/// Only after a successful pop: reading the producer's index on an idle
/// queue would bounce its cache line for nothing.
template <typename Queue>
void noteFill(const Queue& queue, std::atomic<std::uint32_t>& high_water) noexcept {
  const auto fill = static_cast<std::uint32_t>(queue.sizeApprox() + 1);
  if (fill > high_water.load(std::memory_order_relaxed)) high_water.store(fill, std::memory_order_relaxed);
}

}  // namespace

Service::Service(ServiceOptions options, std::vector<std::unique_ptr<SampleSource>> sources)
    : options_(std::move(options)),
      sources_(std::move(sources)),
      participant_(options_.participant),
      publisher_(participant_, options_.publisher),
      localizer_(options_.p_w_anchors, behindTheEntrance(options_.localizer)),
      predictor_(options_.predictor),
      gaps_(checkedTimeoutNs(options_.sensor_silence_s, "sensor_silence_s"),
            checkedTimeoutNs(options_.ranging_silence_s, "ranging_silence_s")),
      trust_(options_.p_w_anchors, localizer_.params().graph) {
  if (sources_.empty()) throw std::invalid_argument("Service: no sample source configured");
  judged_ranges_.reserve(dds::Publisher::kMaxRanges);
  if (!(options_.status_period_s > 0.0)) throw std::invalid_argument("Service: status_period_s must be > 0");
  if (!(options_.init_log_interval_s >= 0.0)) throw std::invalid_argument("Service: init_log_interval_s must be >= 0");
  // Initialization attempts off the estimator thread, which keeps draining
  // the queues meanwhile. Made here, on the constructing thread: the worker
  // takes its normal scheduling, not the estimator's SCHED_FIFO. With
  // backpressure (a replay as fast as possible) no queue can overflow and
  // the data would run ahead of the attempts: inline, as `rilo replay`.
  if (options_.make_init_runner) {
    localizer_.setInitRunner(options_.make_init_runner());
  } else if (!options_.backpressure) {
    localizer_.setInitRunner(std::make_unique<InitWorker>("rilod-init"));
  }
  for (std::size_t i = 0; i < sources_.size(); ++i) {
    // The full screen (jump confirmations included), not the Localizer's copy behind it.
    lanes_.push_back(std::make_unique<SourceLane>(options_.queue_capacity, options_.localizer.screen));
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
    const std::string role = "source " + std::to_string(i);
    source_threads.emplace_back([this, i, role, sink = sinks.back().get()] {
      if (options_.on_thread_enter) options_.on_thread_enter(role.c_str());
      try {
        const SourceEnd end = sources_[i]->run(*sink, stop_sources_);
        if (end == SourceEnd::kFailed) source_failed_.store(true);
      } catch (const std::exception& e) {
        sink->fault(SourceFault{hal::monotonicNowNs(), sources_[i]->describe(), e.what(), true});
      }
      lanes_[i]->ended.store(true, std::memory_order_release);
    });
    if (options_.on_thread_start) options_.on_thread_start(role, source_threads.back());
  }
  std::thread estimator([this] {
    if (options_.on_thread_enter) options_.on_thread_enter("estimator");
    estimatorLoop();
  });
  std::thread publisher([this] {
    if (options_.on_thread_enter) options_.on_thread_enter("publisher");
    publisherLoop();
  });
  if (options_.on_thread_start) {
    options_.on_thread_start("estimator", estimator);
    options_.on_thread_start("publisher", publisher);
  }

  const auto period_ns = static_cast<std::int64_t>(options_.status_period_s * 1e9);
  std::int64_t next_status_ns = hal::monotonicNowNs();
  while (!stop.load() && !estimator_done_.load()) {
    const std::int64_t now = hal::monotonicNowNs();
    status_beat_.beat(now);
    // Follow the wall clock (NTP slew or step) for the published stamps; the
    // samples' clock stays CLOCK_MONOTONIC (dds/stamp_clock.h).
    publisher_.refreshStampOffset();
    if (now >= next_status_ns) {
      publishStatus(now);
      next_status_ns = now + period_ns;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // Tell systemd now, not after the threads are joined (a stop may take a
  // while: sources finish their transfer, the recorder flushes).
  if (stop.load()) {
    stop_requested_.store(true);
    if (options_.on_stop_requested) options_.on_stop_requested();
  }
  stop_sources_.store(true);
  for (std::thread& t : source_threads) t.join();
  stop_threads_.store(true);
  estimator.join();
  publisher.join();
  publishStatus(hal::monotonicNowNs());
  return source_failed_.load() ? 1 : 0;
}

std::vector<notify::WatchedThread> Service::watchedThreads() const {
  std::vector<notify::WatchedThread> threads;
  threads.push_back({"estimator", &estimator_beat_, [this] { return estimator_done_.load(); }});
  threads.push_back({"publisher", &publisher_beat_, [this] { return estimator_done_.load(); }});
  threads.push_back({"status", &status_beat_, [this] { return estimator_done_.load(); }});
  for (std::size_t i = 0; i < lanes_.size(); ++i) {
    const SourceLane* lane = lanes_[i].get();
    threads.push_back({"source " + std::to_string(i) + " (" + sources_[i]->describe() + ")", &lane->beat,
                       [lane] { return lane->ended.load(std::memory_order_acquire); }});
  }
  return threads;
}

bool Service::noteScreened() {
  const InputDropCounts& now = localizer_.inputDropped();
  if (now.total() == screened_.total() && now.time_jumps == screened_.time_jumps) return false;
  auto delta = [&](InputDrop r) { return now[r] - screened_[r]; };
  counters_.non_finite_samples.add(delta(InputDrop::kNotFinite));
  counters_.out_of_order_samples.add(delta(InputDrop::kNonMonotonic));
  counters_.out_of_bounds_samples.add(delta(InputDrop::kOutOfBounds));
  counters_.beyond_full_scale_samples.add(delta(InputDrop::kBeyondFullScale));
  counters_.far_future_samples.add(delta(InputDrop::kFarFuture));
  counters_.time_jumps.add(now.time_jumps - screened_.time_jumps);
  screened_ = now;
  return true;
}

void Service::estimatorLoop() {
  std::vector<UpdateStats> stats;
  std::vector<TimedPose> smoothed;  // drained and dropped, see below
  const std::int64_t imu_silence_ns = secondsToNs(options_.sensor_silence_s);
  const std::int64_t ranging_silence_ns = secondsToNs(options_.ranging_silence_s);
  std::uint64_t rejected_reported = 0;
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
      if (!lane.has_pending) {
        lane.has_pending = lane.samples.tryPop(lane.pending);
        if (lane.has_pending) noteFill(lane.samples, estimator_queue_high_water_);
      }
      if (lane.has_pending) {
        if (oldest < 0 || sampleTime(lane.pending) < sampleTime(lanes_[static_cast<std::size_t>(oldest)]->pending)) {
          oldest = static_cast<int>(i);
        }
        lane.silent.store(false, std::memory_order_relaxed);
        continue;
      }
      const std::int64_t last = lane.last_sample_wall_ns.load(std::memory_order_relaxed);
      const bool quiet = lane.ended.load(std::memory_order_acquire) || (last > 0 && now - last > 20'000'000);
      if (!quiet) all_ready = false;
      const std::int64_t timeout = lane.carries_imu.load(std::memory_order_relaxed) ? imu_silence_ns : ranging_silence_ns;
      if (!lane.ended.load() && last > 0 && now - last > timeout && !lane.silent.load(std::memory_order_relaxed)) {
        lane.silent.store(true, std::memory_order_relaxed);
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
    bool request_status = false;  // a change of state: publish the status now, once it is recorded
    const std::uint64_t reinit_before = localizer_.reinitializations();
    if (const auto* imu = std::get_if<ImuSample>(&lane.pending)) {
      const unsigned events = gaps_.onImu(imu->t_ns);
      if ((events & SensorGapMonitor::kImuGap) != 0) {
        counters_.imu_gaps.add();
        std::lock_guard<std::mutex> lock(stats_mutex_);
        last_imu_gap_ns_ = gaps_.lastImuGapNs();
      }
      if ((events & SensorGapMonitor::kRangingGapStarted) != 0) {
        counters_.ranging_gaps.add();
        request_status = true;
        if (options_.on_event) {
          char text[128];
          std::snprintf(text, sizeof text, "no ranging for %.1f s: %s", static_cast<double>(gaps_.sinceLastRangeNs()) * 1e-9,
                        was_tracking ? "tracking on the IMU alone (degraded)" : "initialization waits for ranges");
          options_.on_event(text);
        }
      }
      ranging_silence_ns_.store(gaps_.rangingSilent() ? gaps_.sinceLastRangeNs() : 0, std::memory_order_relaxed);
      localizer_.addImu(*imu);
    } else if (const auto* range = std::get_if<RangeSample>(&lane.pending)) {
      request_status |= rangingArrived(range->t_ns);
      if (was_tracking) trust_.onRange(*range);
      localizer_.addRange(*range);
    } else if (const auto* tdoa = std::get_if<TdoaSample>(&lane.pending)) {
      // TDoA rows and ultrasonic ranges fix the position too: a TDoA (+
      // ultrasonic) deployment is not "without ranging". Rows the Localizer
      // skips (unknown anchors, deep NLOS) do not: a tag that hears only
      // rows through several walls is without ranging.
      const std::uint64_t gated_before = localizer_.tdoaRowsGated();
      if (localizer_.addTdoa(*tdoa)) request_status |= rangingArrived(tdoa->t_ns);
      if (localizer_.tdoaRowsGated() != gated_before) counters_.deep_nlos_tdoa_rows.add();
    } else if (const auto* us = std::get_if<UltrasonicSample>(&lane.pending)) {
      request_status |= rangingArrived(us->t_ns);
      localizer_.addUltrasonic(*us);
    } else {
      continue;
    }
    request_status |= noteScreened();
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
      trust_.reset();
      request_status = true;
      // The publisher must not keep dead-reckoning from a state the
      // estimator just declared wrong: an invalid state stops the odometry
      // until the next initialization.
      NavigationState invalid;
      invalid.valid = false;
      smoothed_.write(invalid);
      {
        std::lock_guard<std::mutex> lock(stats_mutex_);
        last_failure_ = localizer_.lastFailure();
      }
      if (options_.on_event) options_.on_event("tracking lost: " + localizer_.lastFailure() + "; re-initializing");
    }
    if (!was_tracking && localizer_.tracking()) {
      {
        std::lock_guard<std::mutex> lock(stats_mutex_);
        position_only_ = false;
      }
      trust_.reset();
      trust_.setStateWindow(localizer_.trackingStateWindowNs());
      request_status = true;
      init_attempts_seen_ = 0;
      if (options_.on_event) options_.on_event("initialized: " + localizer_.initStatus().message);
    }
    if (!localizer_.tracking()) {
      noteInitProgress(now);
      publishProvisional();
    }
    tracking_.store(localizer_.tracking() ? TrackingState::kTracking : TrackingState::kInitializing);
    // A change of state is published at once, from here (the periodic status
    // might come only after it is over: a 30 s blackout takes a few ms in a
    // fast replay).
    if (request_status) publishStatus(hal::monotonicNowNs());
    if (updates > 0 && localizer_.tracking()) {
      trust_.judge(localizer_.latest());
      publishJudgedRanges(localizer_.latest().t_ns);
    }
    if (trust_.rejected() != rejected_reported) {
      counters_.rejected_ranges.add(trust_.rejected() - rejected_reported);
      rejected_reported = trust_.rejected();
    }
    if (updates == 0 || !localizer_.tracking()) continue;
    publishSmoothed(navigationState());
    std::lock_guard<std::mutex> lock(stats_mutex_);
    for (const UpdateStats& s : stats) {
      const double ms = s.time_s * 1e3;
      last_update_ms_ = ms;
      sum_update_ms_ += ms;
      max_update_ms_ = std::max(max_update_ms_, ms);
      update_ms_histogram_.add(ms);
      period_max_update_ms_ = std::max(period_max_update_ms_, ms);
      ++updates_;
      if (ms > options_.late_update_ms) counters_.late_updates.add();
      last_stats_ = s;
    }
    if (elapsed_ms > options_.late_update_ms && stats.empty()) counters_.late_updates.add();
  }
  // A stop request does not wait for a start-up attempt; the end of the data
  // takes the one running (within its budget).
  if (stop_requested_.load()) localizer_.abandonInitAttempt();
  // End of data: let the last ranging group through.
  localizer_.finish();
  stats.clear();
  if (localizer_.process(&stats) > 0 && localizer_.tracking()) publishSmoothed(navigationState());
  estimator_done_.store(true);
}

void Service::noteInitProgress(std::int64_t now_ns) {
  const InitStatus& init = localizer_.initStatus();
  if (init.attempts < init_attempts_seen_) init_attempts_seen_ = 0;  // the initializer was reset
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    if (init_message_ != init.message) init_message_ = init.message;
  }
  if (localizer_.initAttemptsOverBudget() != init_over_budget_seen_) {
    init_over_budget_seen_ = localizer_.initAttemptsOverBudget();
    if (options_.on_event) {
      char text[128];
      std::snprintf(text, sizeof text, "initialization attempt still running after its %.1f s budget: told to stop",
                    localizer_.params().init_attempt_budget_s);
      options_.on_event(text);
    }
  }
  if (init.attempts == init_attempts_seen_) return;
  init_attempts_seen_ = init.attempts;
  // Every attempt would be twice a second of data (many per second in a
  // fast replay): log a change of the initializer's state at once, the same
  // state again only after init_log_interval_s.
  const bool changed = init.state != init_state_logged_;
  const bool due = static_cast<double>(now_ns - init_logged_ns_) * 1e-9 >= options_.init_log_interval_s;
  if (!(changed || due || init_logged_ns_ == 0)) return;
  init_state_logged_ = init.state;
  init_logged_ns_ = now_ns;
  if (options_.on_event) {
    options_.on_event("initializing (attempt " + std::to_string(init.attempts) + "): " + init.message);
  }
}

void Service::publishProvisional() {
  const std::optional<Localizer::ProvisionalPosition> fix = localizer_.provisionalPosition();
  if (!fix || fix->sequence == provisional_published_) return;
  provisional_published_ = fix->sequence;
  NavigationState n;
  n.t_ns = fix->t_ns;
  n.p_w_b = fix->p_w_b;
  n.valid = true;  // a pose message, never the odometry's dead-reckoning start (smoothed_ is not written)
  n.pose_covariance.setZero();
  n.pose_covariance.topLeftCorner<3, 3>() = fix->cov_p_w;
  // Orientation unknown: the variance of an angle uniform over (-pi, pi].
  n.pose_covariance.bottomRightCorner<3, 3>() = Mat3::Identity() * (std::numbers::pi * std::numbers::pi / 3.0);
  (void)publisher_.publishPose(n);
  bool first = false;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    first = !position_only_;
    position_only_ = true;
  }
  if (first && options_.on_event) options_.on_event("publishing position only while initializing: " + initPositionText(*fix));
}

void Service::publishJudgedRanges(std::int64_t t_ns) {
  const std::vector<RangeVerdict>& verdicts = trust_.lastVerdicts();
  if (verdicts.empty()) return;
  judged_ranges_.clear();
  for (const RangeVerdict& v : verdicts) {
    if (judged_ranges_.size() == judged_ranges_.capacity()) break;  // never grows: reserved in the constructor
    judged_ranges_.push_back({v.anchor_id, v.range_m, v.predicted_m, v.range_m - v.predicted_m, v.weight,
                              !(v.weight >= RangeTrustMonitor::kTrustedWeight), v.t_offset_ns});
  }
  (void)publisher_.publishRanges(t_ns, judged_ranges_);
}

void Service::publishSmoothed(const NavigationState& state) {
  smoothed_.write(state);
  (void)publisher_.publishPose(state);  // failures show in the status counters of the subscriber side
  const double latency_ms = static_cast<double>(hal::monotonicNowNs() - state.t_ns) * 1e-6;
  std::lock_guard<std::mutex> lock(stats_mutex_);
  pose_latency_ms_ = latency_ms;
}

bool Service::rangingArrived(std::int64_t t_ns) {
  const std::int64_t pause_ns = gaps_.onRange(t_ns);
  ranging_silence_ns_.store(0, std::memory_order_relaxed);
  if (pause_ns > 0 && options_.on_event) {
    char text[96];
    std::snprintf(text, sizeof text, "ranging back after %.1f s", static_cast<double>(pause_ns) * 1e-9);
    options_.on_event(text);
  }
  return pause_ns > 0;
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
  // gyro's, which the output predictor fills per sample
  // (OutputPredictorParams::gyro_noise_density, gyro_bias_sigma).
  n.twist_covariance.setIdentity();
  if (const auto cov = localizer_.latestVelocityCovariance()) n.twist_covariance.topLeftCorner<3, 3>() = *cov;
  return n;
}

void Service::publisherLoop() {
  // Longest sleep without an IMU sample: bounds the reaction to stop and the
  // heartbeat's period while a sensor is silent.
  constexpr std::int64_t kMaxSleepNs = 10'000'000;
  std::uint64_t smoothed_version = 0;
  NavigationState smoothed;
  TimedImu item;
  // Publishes every queued IMU sample; true if there was any.
  auto drain = [&]() noexcept {
    bool any = false;
    for (auto& lane : lanes_) {
      for (bool first = true; lane->imu.tryPop(item); first = false) {
        if (first) noteFill(lane->imu, publisher_queue_high_water_);
        any = true;
        // A newer smoothed state first: the odometry of this sample starts from it.
        if (smoothed_.readIfNewer(smoothed, smoothed_version)) predictor_.onSmoothed(smoothed);
        const NavigationState& out = predictor_.onImu(item.sample);
        // Only an output at this sample's time: when the smoothed state is
        // ahead of this lane, the output stays at the smoothed time, and
        // publishing it once per waiting sample repeated that stamp.
        if (out.valid && out.t_ns == item.sample.t_ns && publisher_.publishOdometry(out).ok()) {
          (void)publisher_.publishTransform(out);  // the same pose and stamp as the odometry
          counters_.published_odometry.add();
          atomicMax(odometry_latency_max_ns_, hal::monotonicNowNs() - item.arrival_ns);
        }
      }
    }
    return any;
  };
  while (!stop_threads_.load(std::memory_order_relaxed)) {
    publisher_beat_.beat(hal::monotonicNowNs());
    if (smoothed_.readIfNewer(smoothed, smoothed_version)) predictor_.onSmoothed(smoothed);
    if (drain()) continue;
    // Nothing queued: sleep until the next IMU sample (its source notifies).
    // Look once more after announcing the wait: a sample pushed just before
    // would not wake us (wake_signal.h).
    const std::uint32_t token = publisher_wake_.prepareWait();
    if (drain()) {
      publisher_wake_.cancelWait();
      continue;
    }
    publisher_wake_.wait(token, kMaxSleepNs);
  }
}

void Service::explain(ServiceStatus& s, const ServiceStatus& previous, std::int64_t now_ns) const {
  std::size_t used = 0;
  s.reason.fill('\0');
  std::lock_guard<std::mutex> lock(stats_mutex_);
  if (s.state == TrackingState::kInitializing) {
    // The note first: the initializer's message may fill the fixed buffer.
    appendReason(s.reason, used, "initializing%s: %s", position_only_ ? " (publishing position only)" : "",
                 init_message_.c_str());
    return;
  }
  if (s.state == TrackingState::kLost) {
    appendReason(s.reason, used, "lost (%s); initializing%s: %s", last_failure_.c_str(),
                 position_only_ ? " (publishing position only)" : "", init_message_.c_str());
    return;
  }
  // Tracking: what is wrong now, then what went wrong during the period.
  if (const std::int64_t silence = ranging_silence_ns_.load(std::memory_order_relaxed); silence > 0) {
    appendReason(s.reason, used, "no ranging for %.1f s (IMU only)", static_cast<double>(silence) * 1e-9);
  }
  for (std::size_t i = 0; i < lanes_.size(); ++i) {
    if (!lanes_[i]->silent.load(std::memory_order_relaxed) || lanes_[i]->ended.load()) continue;
    const std::int64_t last = lanes_[i]->last_sample_wall_ns.load(std::memory_order_relaxed);
    appendReason(s.reason, used, "source %zu silent for %.1f s", i, static_cast<double>(now_ns - last) * 1e-9);
  }
  if (const auto n = increase(s.imu_gaps, previous.imu_gaps)) {
    appendReason(s.reason, used, "%llu IMU gap%s (last %.2f s)", n, n == 1 ? "" : "s",
                 static_cast<double>(last_imu_gap_ns_) * 1e-9);
  }
  if (const auto n = increase(s.ranging_gaps, previous.ranging_gaps); n > 0 && used == 0) {
    appendReason(s.reason, used, "%llu ranging gap%s", n, n == 1 ? "" : "s");
  }
  // Samples dropped at the entrance or by the estimator's screen, one entry per reason.
  struct Dropped {
    std::uint64_t ServiceStatus::*count;
    const char* what;   // before the plural 's'
    const char* after;  // after it
  };
  static constexpr Dropped kDropped[] = {
      {&ServiceStatus::non_finite_samples, "non-finite sample", ""},
      {&ServiceStatus::duplicate_samples, "duplicated sample", ""},
      {&ServiceStatus::out_of_order_samples, "out-of-order sample", ""},
      {&ServiceStatus::out_of_bounds_samples, "out-of-bounds value", ""},
      {&ServiceStatus::beyond_full_scale_samples, "IMU sample", " beyond full scale"},
      {&ServiceStatus::far_future_samples, "far-future sample", ""},
  };
  for (const Dropped& d : kDropped) {
    if (const auto n = increase(s.*d.count, previous.*d.count)) {
      appendReason(s.reason, used, "dropped %llu %s%s%s", n, d.what, n == 1 ? "" : "s", d.after);
    }
  }
  if (const auto n = increase(s.time_jumps, previous.time_jumps)) {
    appendReason(s.reason, used, "%llu IMU time jump%s", n, n == 1 ? "" : "s");
  }
  if (const auto n = increase(s.queue_overflows, previous.queue_overflows)) {
    appendReason(s.reason, used, "%llu sample%s lost to full queues", n, n == 1 ? "" : "s");
  }
  if (const auto n = increase(s.late_updates, previous.late_updates)) {
    appendReason(s.reason, used, "%llu late smoother update%s (max %.0f ms)", n, n == 1 ? "" : "s",
                 period_max_update_ms_);
  }
  if (const auto n = increase(s.sensor_silences, previous.sensor_silences); n > 0 && used == 0) {
    appendReason(s.reason, used, "%llu source silence%s", n, n == 1 ? "" : "s");
  }
  if (increase(s.sensor_faults, previous.sensor_faults) > 0) appendReason(s.reason, used, "fault: %s", last_fault_.c_str());
  if (increase(s.reinitializations, previous.reinitializations) > 0) {
    appendReason(s.reason, used, "re-initialized after: %s", last_failure_.c_str());
  }
}

void Service::publishStatus(std::int64_t now_ns) {
  // The status thread and the estimator (on a change of state) both publish:
  // one at a time, each against the status the other published last.
  std::lock_guard<std::mutex> publishing(status_mutex_);
  const ServiceStatus previous = status_.read();
  ServiceStatus s = previous;
  s.t_ns = now_ns;
  counters_.fill(s);
  s.state = tracking_.load();
  s.odometry_latency_ms = static_cast<double>(odometry_latency_max_ns_.exchange(0, std::memory_order_relaxed)) * 1e-6;
  s.estimator_queue_high_water = estimator_queue_high_water_.load(std::memory_order_relaxed);
  s.publisher_queue_high_water = publisher_queue_high_water_.load(std::memory_order_relaxed);
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    s.last_update_ms = last_update_ms_;
    s.mean_update_ms = updates_ > 0 ? sum_update_ms_ / static_cast<double>(updates_) : 0.0;
    s.max_update_ms = max_update_ms_;
    s.p99_update_ms = update_ms_histogram_.quantileMs(0.99);
    s.last_cliques_reeliminated = static_cast<std::uint32_t>(last_stats_.cliques_reeliminated);
    s.last_relinearized = static_cast<std::uint32_t>(last_stats_.variables_relinearized);
    s.last_lambda = last_stats_.lambda;
    s.pose_latency_ms = pose_latency_ms_;
    std::memset(s.last_fault.data(), 0, s.last_fault.size());
    std::strncpy(s.last_fault.data(), last_fault_.c_str(), s.last_fault.size() - 1);
  }
  // Initializing after having tracked: lost (re-initializing). Tracking with
  // trouble now or during the last period: degraded (explain() says why).
  if (s.state == TrackingState::kInitializing && s.reinitializations > 0) s.state = TrackingState::kLost;
  explain(s, previous, now_ns);
  if (s.state == TrackingState::kTracking && s.reason[0] != '\0') s.state = TrackingState::kDegraded;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    period_max_update_ms_ = 0.0;
  }
  status_.write(s);
  (void)publisher_.publishStatus(s);
  if (options_.on_status) options_.on_status(s);
}

}  // namespace rilo
