#pragma once
// File names and column names of a recording folder (recording-format.md),
// shared by the reader (which columns it needs) and the writer (the header it
// writes: required columns, then optional ones, in this order).
#include <array>
#include <string_view>

namespace rilo::recording {

inline constexpr std::string_view kAnchorsFile = "anchors.csv";
inline constexpr std::string_view kTagsFile = "tags.csv";
inline constexpr std::string_view kImuFile = "imu.csv";
inline constexpr std::string_view kRangeFile = "range.csv";
inline constexpr std::string_view kTdoaFile = "tdoa.csv";
inline constexpr std::string_view kUltrasonicFile = "ultrasonic.csv";
inline constexpr std::string_view kGroundTruthFile = "groundtruth.csv";
inline constexpr std::string_view kMetaFile = "meta.yaml";

inline constexpr std::array<std::string_view, 4> kAnchorsRequired{"id", "x", "y", "z"};
inline constexpr std::array<std::string_view, 2> kAnchorsOptional{"kind", "sigma"};

inline constexpr std::array<std::string_view, 4> kTagsRequired{"id", "x", "y", "z"};
inline constexpr std::array<std::string_view, 0> kTagsOptional{};

inline constexpr std::array<std::string_view, 7> kImuRequired{"t_ns", "wx", "wy", "wz", "ax", "ay", "az"};
inline constexpr std::array<std::string_view, 1> kImuOptional{"temp_c"};

inline constexpr std::array<std::string_view, 3> kRangeRequired{"t_ns", "anchor_id", "range_m"};
inline constexpr std::array<std::string_view, 4> kRangeOptional{"tag_id", "rssi_dbm", "fp_power_dbm", "los"};

inline constexpr std::array<std::string_view, 4> kTdoaRequired{"t_ns", "anchor_a", "anchor_b", "diff_m"};
inline constexpr std::array<std::string_view, 5> kTdoaOptional{"rssi_a_dbm", "fp_power_a_dbm", "rssi_b_dbm",
                                                                 "fp_power_b_dbm", "los"};

inline constexpr std::array<std::string_view, 3> kUltrasonicRequired{"t_ns", "anchor_id", "range_m"};
inline constexpr std::array<std::string_view, 1> kUltrasonicOptional{"los"};

inline constexpr std::array<std::string_view, 8> kGroundTruthRequired{"t_ns", "px", "py", "pz",
                                                                      "qw", "qx", "qy", "qz"};
inline constexpr std::array<std::string_view, 3> kGroundTruthOptional{"vx", "vy", "vz"};

/// Largest accepted deviation of a ground-truth quaternion's norm from 1.
inline constexpr double kQuaternionNormTolerance = 1e-2;

}  // namespace rilo::recording
