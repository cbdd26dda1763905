#pragma once
// Simulated ultrasonic ranging in the office (IMU-Ultrasonic-UWB paper: "4 ultrasonic
// transceivers ... placed at known locations ... 10 Hz"; centimetre-level in
// LOS, short range, easily obstructed).
//
// Beacons hang from the ceiling (placeUltrasonicBeacons; in a hall
// placeHallUltrasonicBeacons, office_hall.h); the receiver sits
// on the body at p_b_receiver (meta ultrasonic.lever_arm). Their anchor ids
// in a recording follow the UWB anchors': N_uwb + j for beacon j, kind
// `ultrasonic`.
//
// Model, per ping:
//  - Beacons ping in turn, beacon j at t_e = r / ping_rate_hz + j / (ping_rate_hz * M)
//    (round r, M beacons); the slot must be long enough for an echo from
//    max_range_m to arrive before the next ping (validate() checks it).
//  - Sound is slow: the ping arrives when |p(t_r) - B| = c (t_r - t_e), c the
//    true speed of sound, p the receiver; t_r is solved by fixed-point
//    iteration and is the sample's t_ns, and the range refers to p(t_r).
//  - A wall between beacon and receiver (full height; doors are gaps) blocks
//    the ping: no measurement, never a biased one. Beyond max_range_m: none.
//  - An obstacle on the path (desk, cabinet, person, or the wearer's body for
//    a beacon behind them) either blocks it (no measurement) or, with
//    reflection_probability, a reflection arrives instead: longer by
//    reflection_min_m + reflection_scale_m * Exp(1) quantile of a smooth field
//    of the receiver position (persistent as the geometry), at most
//    reflection_max_m, los = 0. An echo that would read beyond max_range_m is
//    not detected.
//  - range = (path) * (1 + speed_of_sound_scale_error) + N(0, sigma_m);
//    dropout: pings missed for other reasons.
// Random draws come from their own streams of the seed (office_random.h).
#include <cstdint>
#include <memory>
#include <vector>

#include "sensors/samples.h"
#include "sim/office_random.h"
#include "sim/office_scenario.h"

namespace rilo::sim {

/// Ultrasonic beacons on the ceiling (z = ceiling - mount_below_ceiling_m),
/// `params.beacons` of them. Candidates lie on the long centre line of every
/// space's free rectangle (one per ~6 m); the first beacon goes to the
/// candidate nearest the middle of the floor (the corridor in a corridor
/// plan), each next one to a space with the fewest beacons so far, at the
/// candidate farthest from those already placed. Deterministic; throws
/// std::invalid_argument if the plan has fewer candidates than beacons.
std::vector<Eigen::Vector3d> placeUltrasonicBeacons(const OfficePlan& plan, const UltrasonicParams& params);

/// Anchor id of ultrasonic beacon `beacon` in a recording with `uwb_anchors` UWB anchors.
inline std::uint32_t ultrasonicAnchorId(std::size_t uwb_anchors, std::size_t beacon) {
  return static_cast<std::uint32_t>(uwb_anchors + beacon);
}

/// Truth about one simulated ultrasonic range (evaluation and tests only).
struct UltrasonicTruth {
  std::size_t beacon = 0;         ///< index into setup.p_w_ultrasonic
  double true_range_m = 0.0;      ///< |receiver(t) - beacon| at the sample time (m)
  double excess_m = 0.0;          ///< reflection excess (0 for a direct path) (m)
  double error_m = 0.0;           ///< range_m - true_range_m (m)
  double emit_time_s = 0.0;       ///< ping time since the session start (s)
  Obstruction obstruction;        ///< what is on the direct path
  bool body_blocked = false;
};

/// Ultrasonic ranges one at a time, in time order.
class OfficeUltrasonicStream {
 public:
  /// Uses p.ultrasonic (whether enabled or not), p.seed, p.duration_s,
  /// p.t0_ns and the channel's body-shadowing angles; the beacons are
  /// setup.p_w_ultrasonic (ultrasonicBeaconsOf when empty).
  OfficeUltrasonicStream(const OfficeScenarioParams& p, const OfficeSetup& setup);
  /// Next range and its truth; false at the end of the session.
  bool next(UltrasonicSample& sample, UltrasonicTruth& truth);
  const UltrasonicStats& stats() const { return stats_; }
  double progress() const;
  const std::vector<Eigen::Vector3d>& beacons() const { return beacons_; }
  /// True if the wearer's body blocks the beacon at p_w_beacon for a body in state `body`.
  bool bodyBlocks(const KinematicState& body, const Eigen::Vector3d& p_w_beacon) const;

 private:
  UltrasonicParams up_;
  double duration_s_ = 0.0;
  std::int64_t t0_ns_ = 0;
  std::size_t uwb_anchors_ = 0;
  double body_azimuth_rad_ = 0.0, body_max_elevation_rad_ = 0.0;
  OfficeSetup setup_;
  std::vector<Eigen::Vector3d> beacons_;
  SimRng rng_;
  std::vector<SmoothField> reflection_field_;  ///< per beacon
  std::size_t slot_ = 0;
  double t_s_ = 0.0;
  std::int64_t last_t_ns_ = 0;
  bool done_ = false;
  UltrasonicStats stats_;
};

}  // namespace rilo::sim
