#pragma once
// A person walking through an office (sim/office.h) with a UWB tag and an
// IMU on the body, as a smooth trajectory with exact derivatives.
//
// Planning: random destinations (a point in the free rectangle of a random
// space, sometimes the same one), routed space to space through doors
// (fewest doors); the route steps through each door along its normal, from
// the approach point on one side to the approach point on the other, so it
// only ever leaves a space's free rectangle inside a door opening. At a
// destination the person pauses (sometimes) and turns on the spot. Obstacles
// standing inside a free rectangle (an open hall's desks, shelves, pillars:
// "islands", walk_islands.h) are walked around: destinations are drawn
// outside them and the last stretch to a destination takes the shortest way
// past their corners, 0.3 m + turn_radius_m / 2 from them (the most a rounded
// corner cuts inside the route), so the body keeps ~0.3 m from them. A plan
// without islands draws exactly as before.
//
// Motion: corners of the route are rounded with circular arcs (radius up to
// `turn_radius_m`, never more than half of either adjacent segment), a speed
// profile limits the longitudinal and lateral acceleration (cruise speed
// drawn per leg in [speed_min, speed_max]), and the resulting motion is
// sampled every `control_dt_s` as the control points of uniform cubic
// B-splines in time (position, heading, gait amplitude). Each B-spline is C2
// and lies in the convex hull of 4 consecutive control points, so the walk
// stays within a few centimetres of the rounded route. On top: vertical
// bobbing at the step frequency, lateral sway and trunk roll at half of it,
// pitch oscillation and forward lean, all scaled by the gait amplitude (speed
// / reference speed, zero when standing). Position, velocity, acceleration,
// attitude and body rates are evaluated analytically (exact derivatives of
// the same functions), so the ideal IMU (trajectory.h) is exact.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sim/office.h"
#include "sim/trajectory.h"

namespace rilo::sim {

struct WalkParams {
  std::uint64_t seed = 1;
  double duration_s = 600.0;           ///< planned length; afterwards the person stands still
  double speed_min_m_s = 0.8;          ///< cruise speed of a leg, uniform in [min, max]
  double speed_max_m_s = 1.5;
  double accel_m_s2 = 0.7;             ///< longitudinal acceleration / deceleration limit
  double lateral_accel_m_s2 = 1.2;     ///< turns: v^2 / r at most this
  double turn_radius_m = 0.6;          ///< largest corner rounding radius
  double pause_probability = 0.5;      ///< stop at a destination (else walk on)
  double pause_min_s = 1.0;
  double pause_max_s = 8.0;
  double same_space_probability = 0.3; ///< next destination in the same room
  double initial_still_s = 2.0;        ///< standing still at t = 0 (ignored with start_moving)
  bool start_moving = false;           ///< t = 0 is already at cruise speed on the first leg
  double body_height_m = 1.25;         ///< body frame (IMU) height when standing (m)
  double step_frequency_hz = 1.9;
  double reference_speed_m_s = 1.2;    ///< gait amplitudes below hold at this speed, scale with speed
  double bob_amplitude_m = 0.02;       ///< vertical, at the step frequency
  double sway_amplitude_m = 0.02;      ///< lateral, at half the step frequency
  double roll_amplitude_rad = 0.03;
  double pitch_amplitude_rad = 0.02;
  double yaw_wobble_rad = 0.03;        ///< trunk rotation at half the step frequency
  double lean_rad = 0.04;              ///< forward lean (pitch) at the reference speed
  double turn_rate_rad_s = 1.5;        ///< peak yaw rate turning on the spot
  double control_dt_s = 0.1;           ///< B-spline knot spacing (s)
};

class OfficeWalk final : public Trajectory {
 public:
  /// Plans a walk of at least params.duration_s through `plan` (copied as far
  /// as needed; the walk keeps no reference). Throws std::invalid_argument
  /// naming the parameter for out-of-range params, or if the plan has no space.
  OfficeWalk(const OfficePlan& plan, const WalkParams& params);

  /// State at t_s (s since the start of the walk). Before 0 and after the
  /// planned end the person stands still (continuous: the walk starts and
  /// ends standing, except a start_moving walk before 0).
  KinematicState at(double t_s) const override;

  const WalkParams& params() const { return params_; }
  /// The route before rounding: destinations and door approach points (world xy).
  const std::vector<Eigen::Vector2d>& route() const { return route_; }
  /// End of the planned motion (s); at() holds still after it.
  double plannedEnd() const { return static_cast<double>(pos_.size()) * params_.control_dt_s - lead_s_; }

 private:
  struct Spline1 {
    double v, d, dd;  ///< value, first and second time derivative
  };
  struct Spline2 {
    Eigen::Vector2d v, d, dd;
  };
  /// Knot index and basis at time tau on the control grid.
  struct Basis {
    std::size_t i[4];
    double b[4], db[4], ddb[4];
  };
  Basis basis(double tau) const;

  WalkParams params_;
  std::vector<Eigen::Vector2d> route_;
  std::vector<Eigen::Vector2d> pos_;  ///< control points: horizontal position (m)
  std::vector<double> yaw_;           ///< control points: heading (rad, unwrapped)
  std::vector<double> gait_;          ///< control points: gait amplitude (speed / reference speed)
  double lead_s_ = 0.0;               ///< walk time at t = 0 (start_moving)
};

}  // namespace rilo::sim
