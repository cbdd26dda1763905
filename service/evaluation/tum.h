#pragma once
// Trajectories in the TUM format that evo and most tools read
// (docs: recording-format.md, "Estimator output"): one pose per line,
//   t x y z qx qy qz qw
// t in seconds (nanosecond precision), position of the body origin in the
// world frame (m), quaternion world-from-body in x,y,z,w order (TUM/ROS order;
// Eigen's constructor and our groundtruth.csv take w first).
//
// Reader policy: strict. Lines are split on spaces and tabs; a '#' starts a
// comment that runs to the end of the line; blank and comment-only lines are
// skipped; a trailing '\r' (CRLF files) is ignored. Every other line must be
// a pose, and each of these is an error (TumError, message
// "<file>:<line>: field <n> (<name>): <what>" or "<file>:<line>: <what>" when
// the line as a whole is wrong):
//  - a field count other than 8;
//  - a field that is not a decimal number (std::from_chars general format:
//    no leading '+', no hex) or is nan/inf;
//  - a time not strictly greater than the previous pose's, or outside the
//    int64 nanosecond range;
//  - a quaternion whose norm differs from 1 by more than kTumQuaternionTolerance.
// Times in plain decimal notation are converted to t_ns exactly (digits past
// the ninth decimal are rounded half away from zero); exponent notation goes
// through double. The quaternion is normalised into the rotation matrix.
//
// Writer: the header comment, then `%.9f` time (formatted from t_ns exactly),
// 6 decimals of position, 9 of the quaternion. It writes what it is given
// (no checks): readTum(writeTum(poses)) gives back the times exactly, the
// positions to 5e-7 m and the rotations to ~1e-9.
#include <cstddef>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "estimation/tracking/range_imu_estimator.h"

namespace rilo {

/// A trajectory: poses T_w_b with their times, in time order.
using TumTrajectory = std::vector<RangeImuEstimator::TimedPose>;

/// Largest accepted | |q| - 1 | of a TUM quaternion.
inline constexpr double kTumQuaternionTolerance = 1e-3;

/// A malformed TUM file. `field` is 1-based (1 = t ... 8 = qw; a quaternion
/// norm error names field 5, the first of qx qy qz qw), 0 when the problem
/// concerns the whole line (field count) or the whole file (I/O);
/// `line` is 1-based, 0 for the whole file.
class TumError : public std::runtime_error {
 public:
  TumError(std::string file, std::size_t line, std::size_t field, const std::string& detail);

  const std::string& file() const { return file_; }
  std::size_t line() const { return line_; }
  std::size_t field() const { return field_; }

 private:
  std::string file_;
  std::size_t line_;
  std::size_t field_;
};

/// Name of TUM field `field` (1-based: "t", "x", ..., "qw").
std::string_view tumFieldName(std::size_t field);

/// Parses the whole text of a TUM file; `file` names it in messages.
TumTrajectory parseTum(std::string_view text, const std::string& file);
/// Reads `file`; TumError on an unreadable file or any malformed line.
TumTrajectory readTum(const std::filesystem::path& file);

/// The file content writeTum writes.
std::string formatTum(const TumTrajectory& poses);
/// t_ns as "%.9f" seconds, exactly (not through a double): the TUM files' time field.
std::string secondsText(std::int64_t t_ns);
/// Writes `poses` to `file` (replacing it); std::runtime_error naming the file
/// when it cannot be written.
void writeTum(const std::filesystem::path& file, const TumTrajectory& poses);

}  // namespace rilo
