#pragma once
// rilod's thread structure (docs/architecture.md):
//   source threads --SPSC queues--> estimator thread (Localizer: init,
//   preintegration, D-iSAM2) --seqlock--> publisher thread (IMU-rate output
//   predictor -> odometry topic); the calling thread publishes status.
// The IMU-rate path (source push, publisher loop) neither allocates, locks
// nor logs; overflows, late updates and silences are counted and published.
// Every sample passes the entrance check (sample_screen.h) on its source's
// thread: non-finite, duplicated and out-of-order samples are dropped and
// counted there, so neither the estimator nor the output predictor sees them.
// The state is decided at each status publication (service_status.h): every
// status period, and at once on a change of state seen by the estimator;
// tracking with a ranging gap now, a silent source now, or entrance drops,
// IMU gaps, overflows, late updates or faults during the period is degraded,
// and `reason` says which.
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "dds/participant.h"
#include "dds/publisher.h"
#include "estimation/tracking/localizer.h"
#include "hal/source.h"
#include "rilod/notify.h"
#include "rilod/range_trust_monitor.h"
#include "rilod/sample_screen.h"
#include "rilod/sensor_gap_monitor.h"
#include "runtime/heartbeat.h"
#include "runtime/latency_histogram.h"
#include "runtime/latest_value.h"
#include "runtime/navigation_state.h"
#include "runtime/output_predictor.h"
#include "runtime/runtime_counters.h"
#include "runtime/service_status.h"
#include "runtime/wake_signal.h"

namespace rilo {

struct ServiceOptions {
  std::vector<Vec3> p_w_anchors;      ///< surveyed anchors, index = anchor id (m, world)
  LocalizerParams localizer;
  dds::ParticipantOptions participant;
  dds::PublisherOptions publisher;
  OutputPredictorParams predictor;
  std::size_t queue_capacity = 16384; ///< per source and stream (~20 s of IMU at 800 Hz)
  /// A full queue makes the source wait instead of dropping the sample: for
  /// replay as fast as possible (nothing real-time upstream). Live sources
  /// drop and count.
  bool backpressure = false;
  double status_period_s = 1.0;
  double late_update_ms = 100.0;      ///< a smoother update slower than this counts as late
  /// IMU timeout (s): an IMU interval longer than this (sample time) is an IMU
  /// gap; a source carrying IMU that delivers nothing for this long (wall
  /// clock) is a sensor silence.
  double sensor_silence_s = 1.0;
  /// Ranging timeout (s): no range for this long while the IMU runs (sample
  /// time) is a ranging gap and makes a tracking service degraded; a source
  /// without IMU that delivers nothing for this long (wall clock) is a sensor
  /// silence.
  double ranging_silence_s = 2.0;
  /// The initializer's attempts are logged (on_event) when its state changes,
  /// else at most once per this many seconds (wall clock).
  double init_log_interval_s = 5.0;
  /// Called after each status publication (log, sd_notify): on the thread
  /// that runs Service::run() every status period, and on the estimator
  /// thread at a change of state (tracking started or lost, ranging lost or
  /// back). Never concurrently.
  std::function<void(const ServiceStatus&)> on_status;
  /// Called once per fault from the source's thread (rare path; may log).
  std::function<void(const SourceFault&)> on_fault;
  /// Called when a device started or re-initialized, with what its start-up
  /// read and applied (SourceNote), from the source's thread (rare path; may
  /// log). Sources run concurrently: so may these calls.
  std::function<void(const SourceNote&)> on_note;
  /// Called on notable estimator events: tracking started or lost, ranging
  /// lost and back, initialization progress (rate-limited). Estimator thread.
  std::function<void(const std::string& event)> on_event;
  /// Called once by run() as soon as it sees the stop request, before the
  /// threads are stopped and joined (rilod: STOPPING=1 to systemd).
  std::function<void()> on_stop_requested;
  /// Called for each thread the service starts, before it runs ("source 0",
  /// "estimator", "publisher"): real-time priority and CPU affinity.
  std::function<void(const std::string& role, std::thread& thread)> on_thread_start;
  /// Called first thing ON each thread the service starts, with its role as
  /// above (per-thread instrumentation in tests; must not block).
  std::function<void(const char* role)> on_thread_enter;
  /// Where initialization attempts run (called once, by the constructor).
  /// Empty: an InitWorker thread (runtime/init_worker.h), or inside the
  /// estimator thread with backpressure (nothing overflows, and the data
  /// would run ahead of the attempts). Tests give slow runners.
  std::function<std::unique_ptr<InitAttemptRunner>()> make_init_runner;
};

class Service {
 public:
  /// Throws std::invalid_argument / std::runtime_error on bad options or DDS set-up failure.
  Service(ServiceOptions options, std::vector<std::unique_ptr<SampleSource>> sources);
  ~Service();
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  /// Runs until `stop` is set, or every source ended and its samples were
  /// processed. Returns 0, or 1 when a source failed fatally.
  int run(const std::atomic<bool>& stop);

  /// Snapshot of the status (any thread).
  ServiceStatus status() const { return status_.read(); }
  /// Beats from the estimator and publisher loops (for the systemd watchdog).
  const Heartbeat& estimatorHeartbeat() const { return estimator_beat_; }
  const Heartbeat& publisherHeartbeat() const { return publisher_beat_; }
  /// Every thread the systemd watchdog must see beat: each source, the
  /// estimator, the publisher and the status loop of run() (issue 37: the
  /// estimator's alone kept the pings going under a hung publisher).
  std::vector<notify::WatchedThread> watchedThreads() const;

 private:
  struct SourceLane;
  class LaneSink;

  void estimatorLoop();
  void publisherLoop();
  void publishStatus(std::int64_t now_ns);
  NavigationState navigationState();
  /// A range, TDoA row or ultrasonic range at t_ns (estimator thread): ends a
  /// ranging gap. Returns whether one ended (publish the status now).
  bool rangingArrived(std::int64_t t_ns);
  bool allSourcesDone() const;
  void noteInitProgress(std::int64_t now_ns);
  /// While initializing: a new position-only fix (Localizer::provisionalPosition)
  /// goes out on the pose topic, orientation unknown in its covariance.
  void publishProvisional();
  void judgeRanges();
  void publishSmoothed(const NavigationState& state);
  /// Why the state is `state` (see service_status.h), into status.reason.
  void explain(ServiceStatus& status, const ServiceStatus& previous, std::int64_t now_ns) const;

  ServiceOptions options_;
  std::vector<std::unique_ptr<SampleSource>> sources_;
  std::vector<std::unique_ptr<SourceLane>> lanes_;
  dds::Participant participant_;
  dds::Publisher publisher_;
  Localizer localizer_;
  OutputPredictor predictor_;
  SensorGapMonitor gaps_;       // estimator thread
  RangeTrustMonitor trust_;     // estimator thread
  std::vector<dds::RangeReading> judged_ranges_;  // estimator thread: the last epoch's, for rt/rilo/ranges (reserved)
  /// The ranges trust_ judged last, out on the ranges topic (estimator thread).
  void publishJudgedRanges(std::int64_t t_ns);
  InputDropCounts screened_;    // estimator thread: the screen's counts already in counters_
  /// Moves what the Localizer's physical screen dropped since the last call
  /// into the status counters; true when it dropped anything (estimator thread).
  bool noteScreened();

  LatestValue<NavigationState> smoothed_;
  LatestValue<ServiceStatus> status_;
  RuntimeCounters counters_;
  Heartbeat estimator_beat_, publisher_beat_, status_beat_;
  WakeSignal publisher_wake_;  ///< sources notify per IMU sample; the publisher sleeps on it
  std::atomic<bool> stop_sources_{false};
  std::atomic<bool> estimator_done_{false};
  std::atomic<bool> stop_threads_{false};
  std::atomic<bool> stop_requested_{false};  ///< run() saw the stop request (not the end of the data)
  std::atomic<bool> source_failed_{false};
  std::atomic<TrackingState> tracking_{TrackingState::kInitializing};
  /// Sample time since the last range while ranging is quiet beyond its
  /// timeout (ns), 0 otherwise. Estimator thread writes, status thread reads.
  std::atomic<std::int64_t> ranging_silence_ns_{0};
  /// Worst odometry latency since the status thread last took it (ns).
  std::atomic<std::int64_t> odometry_latency_max_ns_{0};
  /// The newest IMU stamp any source delivered (sample_screen.h judges the
  /// other sources' measurements against it); SampleScreen::kNoImu: none yet.
  std::atomic<std::int64_t> newest_imu_ns_{SampleScreen::kNoImu};

  std::mutex status_mutex_;  ///< serializes publishStatus (status thread, estimator on changes)
  // Estimator statistics (estimator thread writes, status thread reads under the mutex).
  mutable std::mutex stats_mutex_;
  double last_update_ms_ = 0.0, sum_update_ms_ = 0.0, max_update_ms_ = 0.0;
  std::uint64_t updates_ = 0;
  UpdateStats last_stats_;
  double pose_latency_ms_ = 0.0;
  std::string last_fault_;
  std::string init_message_ = "waiting: no samples";  ///< the initializer's status message
  bool position_only_ = false;  ///< a position-only pose went out since initializing began
  std::string last_failure_;                           ///< why tracking last ended
  std::int64_t last_imu_gap_ns_ = 0;
  double period_max_update_ms_ = 0.0;                  ///< slowest update since the last status
  LatencyHistogram update_ms_histogram_;               ///< every update since start (p99)
  /// Fullest queue seen by its consumer (estimator / publisher thread writes, status reads).
  std::atomic<std::uint32_t> estimator_queue_high_water_{0};
  std::atomic<std::uint32_t> publisher_queue_high_water_{0};

  // Estimator thread only: rate limit of the initialization log.
  int init_attempts_seen_ = 0;
  std::uint64_t init_over_budget_seen_ = 0;  ///< Localizer::initAttemptsOverBudget already logged
  InitState init_state_logged_ = InitState::kWaitingForData;
  std::int64_t init_logged_ns_ = 0;
  std::uint64_t provisional_published_ = 0;  ///< sequence of the last position-only fix published
};

}  // namespace rilo
