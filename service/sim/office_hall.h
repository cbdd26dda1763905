#pragma once
// An open hall for the office simulator: the layout of TDoA systems (IMU-Ultrasonic-UWB paper:
// 8 anchors around a 20 m x 15 m area; Crazyflie Loco) and of most TWR
// deployments, where the anchors are installed around the space the person
// moves in, rather than spread over the rooms of a building (office.h).
//
// Plan: one space "hall" [0, x] x [0, y] inside concrete exterior walls, no
// interior walls, no doors. The walk's free rectangle is inset walk_margin_m
// from the wall centrelines and holds the furniture as free-standing islands
// (the walk goes around them, walk.h): concrete pillars, floor to ceiling,
// evenly spaced on the long centre line; desk islands (two desks face to
// face, 0.75 m high, sometimes a seated person beside them); metal shelves
// (2 m high). Desks block only paths that pass low over them (to the low
// anchors), shelves and pillars block at any height. Islands keep aisle_m
// from the walls and from each other, so the floor between them stays
// walkable (the walk keeps 0.6 m from an island with its default turn radius:
// aisle_m above twice that leaves a passage). Placed with a fixed seed: the
// same hall for every simulation seed.
// Anchors: on the walls around the perimeter, heights alternating low and
// high (vertical geometry, as TDoA deployments mount them).
// Ultrasonic beacons: a grid over the free rectangle, on the ceiling.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sim/office.h"
#include "sim/office_sensor_params.h"

namespace rilo::sim {

struct HallLayout {
  Eigen::Vector2d size_m{16.0, 10.0};  ///< footprint [0, x] x [0, y] between the wall centrelines (m)
  double ceiling_m = 3.0;
  double wall_thickness_m = 0.3;       ///< exterior walls, concrete (m)
  double walk_margin_m = 0.7;          ///< free rectangle inset from the wall centrelines (m)
  int pillars = 2;                     ///< on the long centre line, evenly spaced
  double pillar_size_m = 0.5;          ///< square footprint (m)
  int desk_islands = 3;                ///< two desks face to face: 1.4 m x 1.4 m, 0.75 m high
  int shelves = 2;                     ///< metal: 2.0 m x 0.5 m, 2.0 m high, either orientation
  double seated_person_probability = 0.5;  ///< per desk island
  double aisle_m = 1.5;                ///< free floor between islands, and from the walls (m)
  std::uint64_t furniture_seed = 0x4a11ULL;
  double low_anchor_min_m = 0.5;       ///< low anchors' mounting heights, spread over [min, max] (m)
  double low_anchor_max_m = 1.0;
  double high_anchor_min_m = 2.5;      ///< high anchors' mounting heights (m)
  double high_anchor_max_m = 2.8;
};

/// Validates `layout` (std::invalid_argument naming the field).
void validate(const HallLayout& layout);

/// The hall of `layout`, furnished. Islands that find no place (a small hall
/// with many of them) are left out; the pillars always stand.
OfficePlan buildHallPlan(const HallLayout& layout = {});

/// `count` anchors on the walls of a hall plan, wall_offset_m from the wall
/// centrelines: the four corners first (for fewer, diagonal corners first),
/// the rest along the sides in proportion to their length, evenly spaced on
/// each. In order around the perimeter the heights alternate low, high, low,
/// ... (low ones spread over [low_anchor_min_m, low_anchor_max_m] in that
/// order, high ones likewise). Throws std::invalid_argument for count < 1, an
/// offset outside (0.16, 1) m or a plan that is not one space.
std::vector<Eigen::Vector3d> placeHallAnchors(const OfficePlan& plan, const HallLayout& layout, int count,
                                              double wall_offset_m = 0.25);

/// Ultrasonic beacons on the ceiling of a hall plan (z = ceiling -
/// mount_below_ceiling_m) in a grid of cells over the free rectangle (rows
/// and columns in proportion to its sides, the last row possibly shorter),
/// each at its cell's centre, moved off a pillar if one stands there. With
/// the default 4 beacons and 8 m range in the default hall, at least two are
/// within range everywhere on the floor.
std::vector<Eigen::Vector3d> placeHallUltrasonicBeacons(const OfficePlan& plan, const UltrasonicParams& params);

}  // namespace rilo::sim
