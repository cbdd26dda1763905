#pragma once
// An office floor for the simulator: rooms along a corridor, walls with
// thickness and material, doors as gaps in the walls, furniture and people as
// boxes standing on the floor, and UWB anchors mounted on the walls.
//
// World frame: x along the corridor, y across it, z up, the floor at z = 0,
// the footprint [0, size.x] x [0, size.y]. Walls are given by their
// centrelines and reach from floor to ceiling; boxes from the floor to their
// height. Every space (room or corridor) is an axis-aligned rectangle between
// wall centrelines with a convex free rectangle inside it where a person can
// walk (furniture stands only in the strip between the walls and the free
// rectangle); a door joins two spaces, and the walk planner steps through it
// along the door's normal. An open hall (office_hall.h) is one space without
// doors whose free rectangle holds free-standing furniture and pillars
// ("islands": obstacles overlapping a free rectangle); the walk goes around them.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace rilo::sim {

enum class WallMaterial { kDrywall, kConcrete };

struct Wall {
  Eigen::Vector2d a_w = Eigen::Vector2d::Zero();  ///< centreline start, world xy (m)
  Eigen::Vector2d b_w = Eigen::Vector2d::Zero();  ///< centreline end, world xy (m)
  double thickness_m = 0.1;
  WallMaterial material = WallMaterial::kDrywall;
};

enum class ObstacleKind { kDesk, kCabinet, kPerson, kPillar };

/// Axis-aligned box standing on the floor.
struct Obstacle {
  Eigen::Vector2d min_w = Eigen::Vector2d::Zero();  ///< world xy (m)
  Eigen::Vector2d max_w = Eigen::Vector2d::Zero();  ///< world xy (m)
  double height_m = 0.75;
  ObstacleKind kind = ObstacleKind::kDesk;
};

struct Space {
  std::string name;                                  ///< "corridor", "S1", "N2", ...
  bool corridor = false;
  Eigen::Vector2d min_w = Eigen::Vector2d::Zero();   ///< between wall centrelines (m)
  Eigen::Vector2d max_w = Eigen::Vector2d::Zero();
  Eigen::Vector2d free_min_w = Eigen::Vector2d::Zero();  ///< free walking rectangle (convex, no furniture)
  Eigen::Vector2d free_max_w = Eigen::Vector2d::Zero();

  bool contains(const Eigen::Vector2d& p_w) const {
    return (p_w.array() >= min_w.array()).all() && (p_w.array() <= max_w.array()).all();
  }
  bool inFree(const Eigen::Vector2d& p_w, double tol = 1e-9) const {
    return (p_w.array() >= free_min_w.array() - tol).all() && (p_w.array() <= free_max_w.array() + tol).all();
  }
};

/// A gap in a wall between two spaces.
struct Door {
  Eigen::Vector2d center_w = Eigen::Vector2d::Zero();  ///< on the wall centreline (m)
  Eigen::Vector2d normal_w = Eigen::Vector2d::UnitY(); ///< unit, from space_a into space_b
  double width_m = 0.9;
  int space_a = -1;
  int space_b = -1;

  int other(int space) const { return space == space_a ? space_b : space_a; }
};

struct OfficePlan {
  Eigen::Vector2d size_m = Eigen::Vector2d::Zero();  ///< footprint [0, x] x [0, y] (outer wall centrelines)
  double ceiling_m = 3.0;
  std::vector<Space> spaces;  ///< the corridor is spaces[0]
  std::vector<Wall> walls;
  std::vector<Door> doors;
  std::vector<Obstacle> obstacles;

  /// Index of the space containing p_w (first match), -1 outside every space.
  int spaceAt(const Eigen::Vector2d& p_w) const;
  /// Doors of `space` (indices into doors).
  std::vector<int> doorsOf(int space) const;
  /// Point where the walk leaves `space` through `door`: the door centre
  /// projected onto the free rectangle of `space` (straight in front of the door).
  Eigen::Vector2d approachPoint(int door, int space) const;
};

/// Layout of a corridor plan: a corridor along x at y in [corridor_y0,
/// corridor_y1], rooms south (y < corridor_y0) and north of it split at x
/// positions, one door per room into the corridor, optional doors between
/// neighbouring rooms. Exterior walls are concrete.
struct CorridorLayout {
  Eigen::Vector2d size_m{20.0, 12.0};
  double ceiling_m = 3.0;
  double corridor_y0 = 5.0, corridor_y1 = 7.0;
  std::vector<double> south_splits{0.0, 7.0, 14.0, 20.0};  ///< room boundaries along x, first 0, last size.x
  std::vector<double> north_splits{0.0, 6.0, 13.0, 20.0};
  std::vector<double> south_door_x{5.5, 12.0, 15.5};       ///< door centre of each south room
  std::vector<double> north_door_x{2.0, 9.0, 18.0};
  /// Material of the interior walls between rooms, one per interior split.
  std::vector<WallMaterial> south_walls{WallMaterial::kConcrete, WallMaterial::kDrywall};
  std::vector<WallMaterial> north_walls{WallMaterial::kDrywall, WallMaterial::kConcrete};
  struct SideDoor {
    bool north = false;
    int split = 1;     ///< interior split index (1 .. splits.size() - 2)
    double y = 2.5;    ///< door centre (m)
  };
  std::vector<SideDoor> side_doors{{false, 2, 2.5}};
  double door_width_m = 0.9;
  double drywall_thickness_m = 0.12;
  double concrete_thickness_m = 0.2;
  double exterior_thickness_m = 0.3;
  double room_margin_m = 1.0;      ///< free rectangle inset of rooms (furniture strip + clearance)
  double corridor_margin_m = 0.75; ///< free rectangle inset of the corridor across it (0.5 along it + margin)
};

/// Builds the plan of `layout` (no furniture). Throws std::invalid_argument
/// naming the field if the layout is inconsistent (rooms too small for their
/// free rectangle, a door too close to a corner, splits not increasing ...).
OfficePlan buildCorridorPlan(const CorridorLayout& layout);

/// Furniture: desks and cabinets along the walls of the rooms (never in front
/// of a door nor in the free rectangle) and people at the desks.
struct FurnishParams {
  int max_desks_per_room = 3;
  double cabinet_probability = 0.5;
  double seated_person_probability = 0.5;  ///< per desk
  double standing_person_probability = 0.15;  ///< per room
};
void furnish(OfficePlan& plan, std::uint64_t seed, const FurnishParams& params = {});

/// The default floor: 20 m x 12 m, a 2 m corridor, three rooms on each side
/// (one concrete wall on each side, the rest drywall), a door between two
/// south rooms, furnished with a fixed seed. The same for every simulation seed.
OfficePlan defaultOfficePlan();

/// A random corridor floor (16-28 m x 10-16 m, rooms 3.5-7 m wide, doors and
/// wall materials, furniture), deterministic in `seed`.
OfficePlan randomOfficePlan(std::uint64_t seed);

struct AnchorPlacement {
  int count = 8;
  double min_height_m = 2.0;   ///< mounting heights are spread evenly over [min, max], shuffled
  double max_height_m = 2.8;
  double wall_offset_m = 0.25; ///< distance of the anchor from the wall centrelines (m)
  std::uint64_t seed = 0x5eedULL;  ///< order of the heights
};

/// Anchors on the walls, spread over the floor: candidates are the corners
/// and wall midpoints of every space (not in front of a door); each anchor
/// goes to a space with the fewest anchors so far, at the candidate farthest
/// from the anchors already placed (sparse: rooms without an anchor are normal
/// when count < number of spaces). Heights are evenly spread over [min, max]
/// in a shuffled order, so the anchors are never all at one height.
std::vector<Eigen::Vector3d> placeAnchors(const OfficePlan& plan, const AnchorPlacement& placement = {});

/// What the straight path between two points crosses.
struct Obstruction {
  int drywall = 0;
  int concrete = 0;
  int desks = 0;
  int cabinets = 0;
  int people = 0;
  int pillars = 0;

  int walls() const { return drywall + concrete; }
  int total() const { return walls() + desks + cabinets + people + pillars; }
  bool lineOfSight() const { return total() == 0; }
};

/// Walls crossed by the horizontal projection of the segment p_a - p_b (walls
/// are full height) and boxes the 3D segment passes through.
Obstruction obstruction(const OfficePlan& plan, const Eigen::Vector3d& p_a, const Eigen::Vector3d& p_b);

/// Distance from p_w to the nearest wall surface (centreline distance minus
/// half the thickness; negative inside a wall).
double distanceToWalls(const OfficePlan& plan, const Eigen::Vector2d& p_w);

/// True if the 2D segments a0-a1 and b0-b1 intersect (touching counts).
bool segmentsIntersect(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1, const Eigen::Vector2d& b0,
                       const Eigen::Vector2d& b1);

}  // namespace rilo::sim
