#pragma once
// rilod's thread structure (docs/architecture.md):
//   source threads --SPSC queues--> estimator thread (Localizer: init,
//   preintegration, D-iSAM2) --seqlock--> publisher thread (IMU-rate output
//   predictor -> odometry topic); the calling thread publishes status.
// The IMU-rate path (source push, publisher loop) neither allocates, locks
// nor logs; overflows, late updates and silences are counted and published.
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
#include "estimation/pipeline/localizer.h"
#include "hal/source.h"
#include "runtime/heartbeat.h"
#include "runtime/latest_value.h"
#include "runtime/navigation_state.h"
#include "runtime/output_predictor.h"
#include "runtime/runtime_counters.h"
#include "runtime/service_status.h"

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
  double sensor_silence_s = 1.0;      ///< no sample from a source for this long counts as a silence
  /// Called on the status thread after each status publication (log, sd_notify).
  std::function<void(const ServiceStatus&)> on_status;
  /// Called once per fault from the source's thread (rare path; may log).
  std::function<void(const SourceFault&)> on_fault;
  /// Called when tracking starts or ends (from the estimator thread).
  std::function<void(const std::string& event)> on_event;
  /// Called for each thread the service starts, before it runs ("source 0",
  /// "estimator", "publisher"): real-time priority and CPU affinity.
  std::function<void(const std::string& role, std::thread& thread)> on_thread_start;
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

 private:
  struct SourceLane;
  class LaneSink;

  void estimatorLoop();
  void publisherLoop();
  void publishStatus(std::int64_t now_ns);
  NavigationState navigationState();
  bool allSourcesDone() const;

  ServiceOptions options_;
  std::vector<std::unique_ptr<SampleSource>> sources_;
  std::vector<std::unique_ptr<SourceLane>> lanes_;
  dds::Participant participant_;
  dds::Publisher publisher_;
  Localizer localizer_;
  OutputPredictor predictor_;

  LatestValue<NavigationState> smoothed_;
  LatestValue<ServiceStatus> status_;
  RuntimeCounters counters_;
  Heartbeat estimator_beat_, publisher_beat_;
  std::atomic<bool> stop_sources_{false};
  std::atomic<bool> estimator_done_{false};
  std::atomic<bool> stop_threads_{false};
  std::atomic<bool> source_failed_{false};
  std::atomic<TrackingState> tracking_{TrackingState::kInitializing};

  // Estimator statistics (estimator thread writes, status thread reads under the mutex).
  mutable std::mutex stats_mutex_;
  double last_update_ms_ = 0.0, sum_update_ms_ = 0.0, max_update_ms_ = 0.0;
  std::uint64_t updates_ = 0;
  UpdateStats last_stats_;
  double pose_latency_ms_ = 0.0;
  std::string last_fault_;
};

}  // namespace rilo
