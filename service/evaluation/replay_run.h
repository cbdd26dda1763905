#pragma once
// One deterministic run of the online pipeline (Localizer: initialization,
// smoother, recovery) over a recording, as fast as possible: what the service
// would have published at each time (online, causal), the final smoothed
// trajectory, per-update timing and counts. Shared by `rilo replay`,
// `rilo report` and the regression tests, so they all measure the same thing.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "estimation/pipeline/localizer.h"
#include "estimation/pipeline/trajectory_error.h"
#include "evaluation/nlos_classification.h"
#include "evaluation/range_thinning.h"
#include "evaluation/trajectory_metrics.h"  // positionErrorAgainst
#include "hal/recording/recording.h"

namespace rilo {

struct ReplaySettings {
  std::string smoother = "d-isam2";  ///< d-isam2 | isam2 | dogleg
  std::string noise = "asymmetric";  ///< gaussian | huber | cauchy | asymmetric
  double range_hz = 0.0;             ///< thin ranges to this total rate (0: keep all)
  RangeThinning thinning = RangeThinning::kRotate;  ///< which ranges thinning keeps (range_thinning.h)
  double lag_s = 5.0;                ///< fixed lag of the smoother (s)
  // Range noise model (unset: the library defaults, RangeNoiseParams).
  std::optional<double> range_sigma_m;  ///< LOS range std-dev (m)
  std::optional<double> nlos_scale_m;   ///< half-Cauchy scale of the NLOS excess (m)
  std::optional<double> nlos_weight;    ///< prior NLOS probability
  // Height knowledge (unset: LocalizerParams defaults).
  std::optional<bool> height_band;             ///< soft tag height band on tracked states
  std::optional<double> floor_z_m;             ///< floor height in the world frame (m)
  std::optional<double> min_height_m, max_height_m;  ///< band above the floor (m)
  std::optional<double> vertical_speed_sigma_m_s;    ///< vertical speed prior (m/s; 0 none)
  /// Called now and then with the fraction of samples consumed (progress bars).
  std::function<void(double)> progress;
};

/// One smoother update, for timing.csv.
struct ReplayUpdate {
  std::int64_t t_ns = 0;  ///< time of the newest state after the update
  UpdateStats stats;
};

struct ReplayResult {
  std::vector<RangeImuEstimator::TimedPose> online;    ///< newest state after each update
  std::vector<RangeImuEstimator::TimedPose> smoothed;  ///< final estimate of every state, time order
  std::vector<ReplayUpdate> updates;
  std::size_t ranges_used = 0;        ///< after --range-hz thinning
  std::uint64_t initializations = 0;
  std::uint64_t reinitializations = 0;
  std::string last_failure;           ///< why tracking last ended, empty if never
  std::string init_status;            ///< the initializer's last message (why it has not started, if it never did)
  int init_attempts = 0;              ///< initialization attempts (all initializations)
  bool height_band_in_use = false;    ///< the tag height band held the tracked states
  std::string height_band_note;       ///< why a configured height band was dropped
  double data_s = 0.0;                ///< recording duration (IMU span, s)
  double wall_s = 0.0;                ///< time the run took (s)
  /// Present when the recording has ground truth.
  std::optional<PositionErrorStats> ape_online, ape_smoothed;
  /// Ranges the smoothed trajectory down-weights as NLOS (with the run's loss;
  /// scored against the recording's los column when it has one).
  NlosClassification nlos;

  double realtimeFactor() const { return wall_s > 0.0 ? data_s / wall_s : 0.0; }
};

/// Builds the Localizer parameters a replay of `rec` uses (IMU noise and lever
/// arm from its meta.yaml, smoother and noise model from `settings`).
LocalizerParams localizerParamsFor(const Recording& rec, const ReplaySettings& settings);

/// Runs the pipeline over `rec`. Throws std::runtime_error naming the
/// recording when it has no IMU or range samples, std::invalid_argument on bad
/// settings.
ReplayResult replayRecording(const Recording& rec, const ReplaySettings& settings);

}  // namespace rilo
