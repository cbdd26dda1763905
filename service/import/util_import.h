#pragma once
// Importer of the UTIL dataset (UTIAS UWB TDoA, Zhao et al.; docs/util-dataset.md)
// into a rilo recording: one flight CSV (wide layout, one column block per
// sensor, blocks padded with empty fields) plus the anchor survey text file of
// its constellation (anN_p / anN_quat lines).
//
// Parsing is strict: every problem is a RecordingError naming the file, the
// 1-based line and the column ("<file>:<line>: column '<name>': <what>"), in
// the style of the recording reader. Time order per stream: a sample earlier
// than the previous one of its stream, or at the same time with other values
// (TDoA: same pair), is an error, or dropped and counted with
// drop_unordered; a sample identical to the previous one at the same time is
// always dropped and counted.
//
// Units and the TDoA sign are options because a re-exported file may differ
// from the released one; checkPhysics (physics_check.h) verifies them on the
// data and judgeUtilPhysics turns its figures into verdicts naming the option
// to change.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "hal/recording/recording.h"
#include "hal/recording/recording_error.h"
#include "import/physics_check.h"
#include "math/types.h"

namespace rilo::importer {

enum class AccelUnit { kG, kMetersPerSecond2 };
enum class GyroUnit { kDegPerSecond, kRadPerSecond };
/// What tdoa_meas means for the pair (idA, idB).
enum class TdoaSign {
  kBMinusA,  ///< |p - A_idB| - |p - A_idA| (UTIL, Crazyflie firmware; rilo's own convention)
  kAMinusB,  ///< |p - A_idA| - |p - A_idB|
};
/// Whose timestamps the imported IMU samples get; the other stream is
/// interpolated linearly onto them.
enum class ImuClock { kGyro, kAccel };

// Spellings of the command line ("g", "m/s2"; "deg/s", "rad/s"; "b-minus-a",
// "a-minus-b"; "gyro", "accel"). The parsers also accept "m/s^2".
std::string_view toString(AccelUnit unit);
std::string_view toString(GyroUnit unit);
std::string_view toString(TdoaSign sign);
std::string_view toString(ImuClock clock);
std::optional<AccelUnit> accelUnitFromString(std::string_view text);
std::optional<GyroUnit> gyroUnitFromString(std::string_view text);
std::optional<TdoaSign> tdoaSignFromString(std::string_view text);
std::optional<ImuClock> imuClockFromString(std::string_view text);

/// UWB antenna in the Crazyflie body frame (t_uv of the dataset's scripts), m.
inline const Vec3 kUtilTagLeverArm{-0.01245, 0.00127, 0.0908};

struct UtilImportOptions {
  AccelUnit accel_unit = AccelUnit::kG;
  GyroUnit gyro_unit = GyroUnit::kDegPerSecond;
  TdoaSign tdoa_sign = TdoaSign::kBMinusA;
  ImuClock imu_clock = ImuClock::kGyro;
  double gravity_m_s2 = 9.81;          ///< g -> m/s^2 and meta.yaml gravity (the dataset's scripts use 9.81)
  Vec3 lever_arm_m = kUtilTagLeverArm;  ///< UWB antenna, body frame (m) -> meta.yaml uwb.lever_arm
  double max_imu_gap_s = 0.05;         ///< interpolation partner samples further apart: the IMU sample is dropped
  bool drop_unordered = false;         ///< drop and count out-of-order samples instead of failing
};

/// Samples of one stream of the flight CSV.
struct StreamCounts {
  std::size_t rows = 0;        ///< samples in the file
  std::size_t kept = 0;        ///< samples imported
  std::size_t duplicates = 0;  ///< identical to the previous sample at the same time: dropped
  std::size_t unordered = 0;   ///< out of order (drop_unordered): dropped
  std::size_t first_duplicate_line = 0;  ///< 1-based, 0 = none
  std::size_t first_unordered_line = 0;
};

struct UtilSurvey {
  std::string file;              ///< as given, for messages and meta.yaml
  std::vector<Anchor> anchors;   ///< sorted by id, kind uwb
  std::size_t orientations = 0;  ///< anN_quat lines checked (and dropped: rilo has no anchor orientation)
};

struct UtilImport {
  Recording recording;           ///< meta, anchors, imu, tdoa, groundtruth
  std::string flight_file;
  std::string survey_file;
  UtilImportOptions options;
  StreamCounts tdoa, accel, gyro, pose;
  std::size_t imu_without_partner = 0;  ///< clock samples without interpolation partners within max_imu_gap_s
  std::size_t survey_orientations = 0;
  ReadReport report;             ///< warnings (unknown columns, blank lines, ...)
};

/// Parses an anchor survey text file (anchor_constN_survey.txt). Throws RecordingError.
UtilSurvey parseUtilSurvey(std::string_view text, const std::string& file);

/// Parses one flight CSV; tdoa ids must be anchors of `survey`. Throws
/// RecordingError on bad data, std::invalid_argument on bad options.
UtilImport parseUtilFlight(std::string_view text, const std::string& file, const UtilSurvey& survey,
                           const UtilImportOptions& options);

/// Reads both files (RecordingError if unreadable) and parses them.
UtilImport importUtil(const std::filesystem::path& flight_csv, const std::filesystem::path& survey_txt,
                      const UtilImportOptions& options);

/// Writes the imported recording into `dir` with RecordingWriter (refuses an
/// existing recording unless `overwrite`).
void writeUtilRecording(const UtilImport& imported, const std::filesystem::path& dir, bool overwrite);

enum class CheckStatus {
  kOk,
  kContradiction,  ///< the data contradicts a chosen option: the import fails unless forced
  kInconclusive,   ///< the check could not decide, or found something odd that no option explains: a warning
};
std::string_view toString(CheckStatus status);

struct CheckVerdict {
  std::string item;     ///< "accel unit", "gyro unit", "tdoa sign", "lever arm", "tdoa bias"
  CheckStatus status = CheckStatus::kInconclusive;
  std::string message;  ///< figures and, for a contradiction, the option to change
};

/// Verdicts on the physics check of a recording imported with `options`.
std::vector<CheckVerdict> judgeUtilPhysics(const PhysicsCheck& check, const UtilImportOptions& options);

bool anyContradiction(const std::vector<CheckVerdict>& verdicts);

/// Human-readable summary: counts per stream, IMU rate, check figures and verdicts.
std::string formatUtilSummary(const UtilImport& imported, const PhysicsCheck& check,
                              const std::vector<CheckVerdict>& verdicts);

}  // namespace rilo::importer
