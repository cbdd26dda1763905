#pragma once
// rilod's configuration: the struct tree the service runs from and its strict
// YAML loader. config/README.md documents every key; config/rilod.yaml (replay
// demo) and config/rilod-hardware.yaml are complete examples.
//
// Loading is strict: unknown keys, wrong types, out-of-range values, missing
// required keys, contradictory settings and a missing anchors file are all
// errors, thrown as one ConfigError naming the file, the key path
// ("estimator.smoother"), what was expected and the line/column. Nothing is
// opened besides the configuration and the anchors file: device nodes, the
// replay recording and the BMI263 blob are checked when the service opens them
// (so the examples load on any machine).
//
// Paths. Every relative path in the file (sources.replay.path, anchors.file,
// recording.directory, dds.cyclone_config_file, ...bmi263.config_blob_path)
// is resolved against the directory that contains the configuration file, and
// stored absolute and lexically normal. Device nodes (/dev/...) are kept as
// written.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "dds/stamp_clock.h"
#include "dds/topics.h"
#include "estimation/assembly/range_imu_graph.h"
#include "estimation/assembly/range_imu_graph_stream.h"
#include "estimation/measurements/range_consistency.h"
#include "estimation/smoother/smoother_params.h"
#include "estimation/tracking/localizer.h"
#include "hal/bmi263/bmi263_config.h"
#include "hal/dw3000/dw3000_config.h"
#include "hal/recording/recording.h"
#include "rilod/fault_injection.h"
#include "runtime/realtime.h"

namespace rilo {

/// A configuration error. what() is "<file>:<line>:<column>: <key path>: <detail>"
/// (without line/column when the position is unknown, e.g. a missing file).
class ConfigError : public std::invalid_argument {
 public:
  ConfigError(std::string file, std::string key_path, int line, int column, std::string detail);

  const std::string& file() const noexcept { return file_; }
  /// Dotted path of the offending key ("estimator.smoother", "anchors.list[2].x");
  /// "(top level)" for the document itself.
  const std::string& keyPath() const noexcept { return key_path_; }
  int line() const noexcept { return line_; }      ///< 1-based; 0 if unknown
  int column() const noexcept { return column_; }  ///< 1-based; 0 if unknown
  const std::string& detail() const noexcept { return detail_; }

 private:
  std::string file_, key_path_;
  int line_, column_;
  std::string detail_;
};

// --- sources ---------------------------------------------------------------

enum class SourceMode { kReplay, kHardware };
enum class ReplayPace { kRealTime, kAsFastAsPossible };

struct ReplaySourceConfig {
  std::filesystem::path path;           ///< recording folder (absolute)
  ReplayPace pace = ReplayPace::kRealTime;
  double speed = 1.0;                   ///< recording seconds per clock second (real_time only), > 0
  bool loop = false;                    ///< replay again from the start at the end of the data
  /// Shift sample times so the first one carries the clock's time at start
  /// (real_time only): replayed samples then look live (latency figures,
  /// one clock with the service). See ReplayOptions::shift_to_now.
  bool shift_to_now = true;
  /// Faults injected into the replayed stream (fault_injection.h), for tests
  /// and demonstrations of the service's fault handling. Empty: none.
  std::vector<FaultSpec> faults;
};

/// One GPIO line of a gpiochip character device.
struct GpioLineConfig {
  std::string chip = "gpiochip0";  ///< "gpiochipN" or "/dev/gpiochipN"
  unsigned line = 0;               ///< line offset on that chip
};

struct UwbHardwareConfig {
  std::string spi_device = "/dev/spidev0.0";
  GpioLineConfig irq;                    ///< DW3000 IRQ output (rising edge)
  std::optional<GpioLineConfig> reset;   ///< RSTn, driven by us if given
  dw3000::Dw3000Config dw3000;           ///< radio, timing, anchors' short addresses (validated)
};

struct ImuHardwareConfig {
  std::string i2c_device = "/dev/i2c-1";
  std::uint8_t i2c_address = 0x68;       ///< 7-bit; BMI263: 0x68 (SDO low) or 0x69
  GpioLineConfig irq;                    ///< BMI263 INT1 (rising edge)
  bmi263::Bmi263Config bmi263;           ///< validated
};

struct HardwareSourceConfig {
  UwbHardwareConfig uwb;
  ImuHardwareConfig imu;
};

struct SourcesConfig {
  SourceMode mode = SourceMode::kReplay;
  ReplaySourceConfig replay;             ///< meaningful when mode == kReplay
  HardwareSourceConfig hardware;         ///< meaningful when mode == kHardware
};

// --- estimator -------------------------------------------------------------

/// SmootherParams with the service's default lag (10 s): the library's
/// default 0 keeps every state, which a long-running service cannot. And the
/// service's real-time bounds (docs/smoother.md, "The real-time tail"):
/// - wildfire 0.01: a delta change below 1 cm / 10 mrad is not carried into
///   older cliques (GTSAM's 1e-3 re-solved ~170 of ~370 cliques on every
///   40 Hz update; the online error was the same within 0.005 m);
/// - anchors (L(j), symbol 'l') relinearize at 0.1 m: each anchor is in
///   every range factor of the window, so relinearizing one re-eliminates
///   the whole tree (5-6 ms), and a range's curvature in the anchor is
///   1/range: 0.1 m off the linearization point costs < 5 mm at 1 m;
/// - no running nonlinear error (SmootherParams::track_error): nothing in
///   the service reads it, and its refresh was 14 % of a replay.
inline SmootherParams serviceSmootherDefaults() {
  SmootherParams p;
  p.lag_s = 10.0;
  p.track_error = false;
  p.wildfire_threshold = 0.01;
  p.relinearize_thresholds3['l'] = Vec3::Constant(0.1);
  return p;
}

struct EstimatorConfig {
  /// method (d-isam2 / isam2 / dogleg), lag, damping schedule, trust region,
  /// relinearization. lag_s > 0 always (bounded memory).
  SmootherParams smoother = serviceSmootherDefaults();
  /// Range noise model, anchors as variables, lever arm, state spacing.
  /// graph.imu is filled from the top-level `imu` section.
  RangeImuGraphParams graph;
  RangeImuStreamOptions stream;
  /// Start-up: batch solve over this many seconds of data before the
  /// incremental smoother takes over (Ranging-IMU Fusion paper: 10 s).
  double init_window_s = 10.0;
  /// Start-up refuses a solution whose tag lies farther than this beyond the
  /// anchors' horizontal box (m; InitializerParams::max_outside_anchors_m; .inf: off).
  double init_max_outside_anchors_m = InitializerParams().max_outside_anchors_m;
  /// Start-up widens its cost gates for heavy NLOS this long after the first
  /// two-way range without a start (s; InitializerParams::heavy_nlos_after_s; .inf: off).
  double init_heavy_nlos_after_s = InitializerParams().heavy_nlos_after_s;
  /// Wall time an initialization attempt on the worker thread may take before
  /// it is told to stop unfinished (s; LocalizerParams::init_attempt_budget_s; .inf: no bound).
  double init_attempt_budget_s = LocalizerParams().init_attempt_budget_s;
  /// Quantile of the flagged ranges' residuals taken as their excess (FlaggedExcessParams; 0: off).
  double flagged_excess_quantile = FlaggedExcessParams().quantile;
  /// Lower nlos_power_gap_db to where the ranges show the LOS gaps end (LosGapParams).
  bool los_gap_calibration = LosGapParams().enabled;
  /// Ranges without first-path power: the RX level's deficit below the
  /// learnt LOS envelope as their NLOS indicator (RxLevelEnvelopeParams).
  bool rx_level_indicator = RxLevelEnvelopeParams().enabled;
  /// Ranges without first-path power: an anchor whose last two ranges the
  /// mixture took as NLOS within this has its next one flagged (s;
  /// NlosMemoryParams::window_s; 0: off).
  double nlos_memory_s = NlosMemoryParams().window_s;
  /// Tag height band above the floor (a wearable's height; see
  /// estimation/measurements/height_band.h): initialization and every state.
  HeightBand height_band;
  /// Zero vertical-speed prior (m/s std-dev per graph.vertical_speed_correlation_s;
  /// 0 = none); unset ("auto"): on the tracked states, 0.016 when the ranging
  /// is TDoA, else 0.1 (LocalizerParams::vertical_speed_sigma_m_s).
  std::optional<double> vertical_speed_sigma_m_s;
  /// Zero-velocity prior on each tracked state the IMU shows still (m/s per
  /// second of standstill; 0 = none; LocalizerParams::zero_velocity_sigma_m_s).
  double zero_velocity_sigma_m_s = LocalizerParams().zero_velocity_sigma_m_s;
  /// Tracking ends (and initialization restarts) when the tag is estimated
  /// farther than this beyond the anchors' horizontal bounding box while
  /// ranging holds the estimate (ranging_support.h) (m; .inf: off).
  double max_outside_anchors_m = 10.0;  // as LocalizerParams (config_test checks they agree)
  /// The physical screen in front of the estimator (estimation/measurements/input_screen.h;
  /// section `input_screen`). With the BMI263 as the IMU source and no
  /// accel/gyro bound given, the bounds are its configured full scales.
  InputScreenParams input_screen;
  bool input_screen_imu_bounds_given = false;
  /// State window and per-link sigmas once the data hold TDoA rows (`tdoa`
  /// section; LocalizerParams::with_tdoa).
  LocalizerParams::WithTdoa with_tdoa;
};

// --- output, recording, run-time ---------------------------------------------

struct DdsConfig {
  std::uint32_t domain_id = 0;                ///< 0..232 (ROS_DOMAIN_ID)
  /// Keep all DDS traffic on 127.0.0.1 (dds::loopbackConfigXml()); for
  /// single-host demos and tests.
  bool loopback_only = false;
  /// Cyclone DDS XML configuration file (absolute); empty = Cyclone's defaults
  /// (CYCLONEDDS_URI). Exclusive with loopback_only.
  std::filesystem::path cyclone_config_file;
  /// Clock of the published stamps: system time (ROS 2) or rilo's
  /// CLOCK_MONOTONIC (dds/stamp_clock.h).
  dds::StampClock stamp_clock = dds::StampClock::kSystem;
  dds::TopicNames topics;
  dds::FrameIds frames;
};

struct RecordingConfig {
  bool enabled = false;
  /// Parent folder: each run records into a new sub-folder (see
  /// newRecordingDirectory in recorder.h). Absolute.
  std::filesystem::path directory = "/var/lib/rilo/recordings";
  std::int64_t flush_interval_ns = 200'000'000;  ///< a crash loses at most this much
  bool sync = false;                             ///< fdatasync per flush (power loss too)
};

struct RealtimeConfig {
  ProcessRealtimeSettings process;
  std::size_t queue_capacity = 4096;   ///< samples per source queue (rounded up to a power of two)
  ThreadRealtimeSettings imu_source{"rilo-imu", 80, {}};
  ThreadRealtimeSettings uwb_source{"rilo-uwb", 80, {}};
  ThreadRealtimeSettings replay_source{"rilo-replay", 80, {}};
  ThreadRealtimeSettings publisher{"rilo-publisher", 70, {}};
  ThreadRealtimeSettings estimator{"rilo-estimator", 0, {}};
  ThreadRealtimeSettings recorder{"rilo-recorder", 0, {}};
};

struct StatusConfig {
  std::int64_t period_ns = 1'000'000'000;        ///< status topic and systemd STATUS= line
  std::int64_t imu_timeout_ns = 100'000'000;     ///< IMU quiet this long: a sensor silence
  std::int64_t range_timeout_ns = 2'000'000'000; ///< ranging quiet this long: a sensor silence
};

struct WatchdogConfig {
  /// Ping systemd (WATCHDOG=1) when the unit sets WatchdogSec; false never pings.
  bool enabled = true;
  /// The real-time loop's heartbeat must be at most this old for a ping.
  std::int64_t heartbeat_timeout_ns = 1'000'000'000;
  /// Pings continue this long after start-up until the loop's first beat
  /// (DDS discovery, initialization window). See WatchdogPingerOptions.
  std::int64_t startup_grace_ns = 30'000'000'000;
};

struct ServiceConfig {
  std::filesystem::path file;            ///< the configuration file (absolute)
  SourcesConfig sources;
  /// Surveyed anchors (UWB and ultrasonic), world frame. At least 3 UWB anchors.
  std::vector<Anchor> anchors;
  std::filesystem::path anchors_file;    ///< where they came from (absolute); empty when inline
  EstimatorConfig estimator;             ///< estimator.graph.imu = the `imu` section
  DdsConfig dds;
  RecordingConfig recording;
  RealtimeConfig realtime;
  StatusConfig status;
  WatchdogConfig watchdog;
};

/// Reads and checks `file`. Throws ConfigError (also for a missing or
/// unreadable file).
ServiceConfig loadServiceConfig(const std::filesystem::path& file);

/// Parses `yaml` as if it were the content of `file` (used in messages; its
/// directory is the base of relative paths). Throws ConfigError.
ServiceConfig parseServiceConfig(std::string_view yaml, const std::filesystem::path& file);

/// The estimator of a rilod configuration document alone: its `imu` and
/// `estimator` sections, checked as loadServiceConfig checks them (the root's
/// keys too, so a misspelt section is still an error). The other sections
/// are not read: no anchors file is opened, no device named. For running the
/// service's estimator on recorded data (`rilo replay`). Throws ConfigError.
EstimatorConfig parseEstimatorConfig(std::string_view yaml, const std::filesystem::path& file);

std::string_view toString(SourceMode mode);
std::string_view toString(ReplayPace pace);

}  // namespace rilo
