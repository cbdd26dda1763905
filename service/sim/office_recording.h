#pragma once
// Simulated sessions written as recording folders (docs/recording-format.md)
// with RecordingWriter:
//   meta.yaml        name, description, gravity, imu rate and noise model,
//                    uwb.lever_arm = p_b_tag, ranging: ss-twr
//   anchors.csv      id = index in p_w_anchors, kind uwb
//   tags.csv         one antenna, id 0, at p_b_tag (the same as uwb.lever_arm)
//   imu.csv          every IMU sample
//   range.csv        every range with tag_id 0, rssi_dbm, fp_power_dbm, los
//   tdoa.csv, ultrasonic.csv  (office sessions with TDoA / ultrasonic, see
//                    writeOfficeRecording; meta ranging: tdoa, ultrasonic.lever_arm)
//   groundtruth.csv  pose and velocity of the truth trajectory at
//                    truth_rate_hz on the IMU clock (t0_ns + k / rate, up to
//                    the session's duration)
// Reading the folder back (readRecording) gives exactly these samples.
// (This file is why rilo_sim links rilo_recording.)
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "hal/recording/recording.h"
#include "hal/recording/recording_writer.h"
#include "sim/office_scenario.h"
#include "sim/range_imu_scenario.h"

namespace rilo::sim {

struct ScenarioRecordingOptions {
  std::string name = "rilo-sim";
  std::string description;
  double truth_rate_hz = 200.0;   ///< groundtruth.csv rate (Hz), (0, imu rate]
  RecordingWriterOptions writer;  ///< overwrite, flushing; imu_temperature is ignored (no temp_c)
  /// Called now and then with the fraction of the work done, in [0, 1] (may be empty).
  std::function<void(double fraction)> progress;
};

/// meta.yaml content of a simulated session.
RecordingMeta scenarioMeta(const ScenarioParams& params, const Eigen::Vector3d& p_b_tag,
                           const ScenarioRecordingOptions& options);
/// anchors.csv content: id = index, uwb, no survey sigma.
std::vector<Anchor> scenarioAnchors(const std::vector<Eigen::Vector3d>& p_w_anchors);
/// Ground-truth times: t0_ns + round(k / rate_hz s) for k = 0 .. floor(duration_s * rate_hz).
std::vector<std::int64_t> groundTruthTimes(std::int64_t t0_ns, double duration_s, double rate_hz);
/// The truth pose and velocity at t_ns (quaternion with w >= 0).
GroundTruthPose groundTruthAt(const Scenario& s, std::int64_t t_ns);

/// Writes `s` into `dir` (created if needed; an existing recording there is
/// an error unless options.writer.overwrite). Throws std::invalid_argument
/// for bad options, std::system_error for I/O failures.
void writeScenarioRecording(const Scenario& s, const std::filesystem::path& dir,
                            const ScenarioRecordingOptions& options = {});

/// Simulates the office session of `params` and writes it into `dir` sample by
/// sample, without holding the session in memory: the same files as
/// writeScenarioRecording(simulateOffice(params).scenario, dir, options).
/// With params.tdoa.enabled, meta says `ranging: tdoa`, tdoa.csv holds the
/// OfficeTdoaStream samples and range.csv is written only with
/// params.tdoa.keep_twr. With params.ultrasonic.enabled, anchors.csv also
/// lists the beacons (kind ultrasonic, ids after the UWB anchors), meta gets
/// ultrasonic.lever_arm and ultrasonic.csv the OfficeUltrasonicStream
/// samples. Without either, the files are exactly those of before they existed.
/// Returns the statistics of the session (stats.tdoa, stats.ultrasonic filled
/// when enabled; the SS-TWR counters are zero when TDoA replaces it).
OfficeStats writeOfficeRecording(const OfficeScenarioParams& params, const std::filesystem::path& dir,
                                 const ScenarioRecordingOptions& options = {});

}  // namespace rilo::sim
