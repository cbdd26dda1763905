#pragma once
// In-memory form of one recording folder (docs: recording-format.md). The
// reader fills it, the writer and the simulator produce it, replay and
// evaluation consume it. Plain data: every field keeps exactly what the files
// say (no normalisation, no defaults invented beyond those the format states),
// so write -> read gives back identical content.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "math/pose3.h"
#include "math/types.h"
#include "sensors/samples.h"

namespace rilo {

enum class AnchorKind { kUwb, kUltrasonic };

/// Fixed transmitter surveyed in the world frame (anchors.csv).
struct Anchor {
  std::uint32_t id = 0;
  Vec3 p_w_anchor = Vec3::Zero();        ///< surveyed position, world frame (m)
  AnchorKind kind = AnchorKind::kUwb;
  std::optional<double> sigma_m;         ///< prior std-dev of the surveyed position (m), if given
};

/// UWB antenna on the body (tags.csv).
struct Tag {
  std::uint32_t id = 0;
  Vec3 p_b_tag = Vec3::Zero();           ///< lever arm, body frame (m)
};

/// True body pose (groundtruth.csv, evaluation only). The quaternion is kept
/// exactly as stored (file order w,x,y,z); pose() normalises it.
struct GroundTruthPose {
  std::int64_t t_ns = 0;
  Vec3 p_w_b = Vec3::Zero();             ///< body origin in world (m)
  Quat q_w_b = Quat::Identity();         ///< world-from-body rotation
  std::optional<Vec3> v_w_b;             ///< body velocity in world (m/s), if the file has vx,vy,vz

  Pose3 pose() const { return Pose3(q_w_b, p_w_b); }
};

enum class RangingKind { kSsTwr, kDsTwr, kTdoa };

/// "ss-twr", "ds-twr", "tdoa" (the spellings of meta.yaml).
std::string_view toString(RangingKind kind);
std::optional<RangingKind> rangingKindFromString(std::string_view text);
/// "uwb", "ultrasonic" (the spellings of anchors.csv).
std::string_view toString(AnchorKind kind);
/// Surveyed UWB anchor positions indexed by anchor id, as the estimators take
/// them. Ids without a UWB anchor hold a far-away placeholder (1e6 m), which no
/// range can reference: the recording reader and rilod's config reject ranges
/// to unknown anchors.
std::vector<Vec3> uwbAnchorsById(const std::vector<Anchor>& anchors);
/// The same for the ultrasonic beacons (RangeImuGraphParams::p_w_ultrasonic).
std::vector<Vec3> ultrasonicBeaconsById(const std::vector<Anchor>& anchors);
std::optional<AnchorKind> anchorKindFromString(std::string_view text);

/// meta.yaml. Optional members are absent when the file does not give them.
struct RecordingMeta {
  std::string name;
  std::string description;
  double gravity_m_s2 = 9.81;                        ///< |g|; gravity is (0, 0, -g) in world
  std::optional<double> imu_rate_hz;
  std::optional<double> gyro_noise_density;          ///< rad/s/sqrt(Hz)
  std::optional<double> accel_noise_density;         ///< m/s^2/sqrt(Hz)
  std::optional<double> gyro_bias_random_walk;       ///< rad/s^2/sqrt(Hz)
  std::optional<double> accel_bias_random_walk;      ///< m/s^3/sqrt(Hz)
  // The device's geometry. Absent when meta.yaml does not say it: a replay
  // with a service configuration then keeps the configuration's.
  std::optional<Vec3> uwb_lever_arm_m;               ///< single UWB antenna, body frame (m); used when tags is empty
  std::optional<Vec3> ultrasonic_lever_arm_m;        ///< ultrasonic receiver, body frame (m)
  Vec3 uwbLeverArm() const { return uwb_lever_arm_m.value_or(Vec3::Zero()); }          ///< absent: at the body origin
  Vec3 ultrasonicLeverArm() const { return ultrasonic_lever_arm_m.value_or(Vec3::Zero()); }
  std::optional<RangingKind> ranging;
};

struct Recording {
  RecordingMeta meta;
  std::vector<Anchor> anchors;
  std::vector<Tag> tags;                  ///< empty: one antenna (tag id 0) at meta.uwbLeverArm()
  std::vector<ImuSample> imu;
  std::vector<double> imu_temp_c;         ///< empty if imu.csv has no temp_c column, else one per imu sample (NaN = blank)
  std::vector<RangeSample> ranges;
  std::vector<TdoaSample> tdoa;
  std::vector<UltrasonicSample> ultrasonic;
  std::vector<GroundTruthPose> groundtruth;

  /// nullptr if there is no anchor with this id.
  const Anchor* findAnchor(std::uint32_t id) const;
  /// Lever arm of the UWB antenna `tag_id` (body frame, m), nullopt if there
  /// is no such antenna (tags empty: only id 0, at meta.uwbLeverArm()).
  std::optional<Vec3> findTagLeverArm(std::uint32_t tag_id) const;
};

}  // namespace rilo
