#pragma once
// Free-standing obstacles in a space's free rectangle ("islands": an open
// hall's desks, shelves and pillars, office_hall.h) and the shortest way
// around them, for the walk planner (walk.h). A corridor plan has none: its
// furniture keeps to the strip between the walls and the free rectangles.
//
// Each island is the obstacle's footprint grown by the walk's clearance; a
// way around them is the shortest path through the visibility graph of their
// corners (grown a further 2 cm, so the path runs just outside them).
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "sim/office.h"

namespace rilo::sim {

class WalkIslands {
 public:
  /// The obstacles of `plan` that overlap the free rectangle of `space`, grown by clearance_m.
  WalkIslands(const OfficePlan& plan, const Space& space, double clearance_m);

  bool empty() const { return lo_.empty(); }
  /// True if the segment a-b touches no island (a == b: the point is outside them).
  bool clear(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// The corners to pass on the shortest way from a to b (empty if the
  /// straight line is clear), or nothing if b cannot be reached.
  std::optional<std::vector<Eigen::Vector2d>> wayAround(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

 private:
  std::vector<Eigen::Vector2d> lo_, hi_;  ///< grown island boxes
  std::vector<Eigen::Vector2d> corners_;  ///< visibility graph nodes inside the free rectangle
};

}  // namespace rilo::sim
