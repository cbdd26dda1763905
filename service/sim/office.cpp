#include "sim/office.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "sim/office_random.h"

namespace rilo::sim {
namespace {

using Vec2 = Eigen::Vector2d;

[[noreturn]] void invalid(const std::string& what) { throw std::invalid_argument(what); }

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// Wall from a to b with gaps (centre distance from a along the wall, width).
void addWallWithGaps(OfficePlan& plan, const Vec2& a, const Vec2& b, double thickness, WallMaterial material,
                     std::vector<std::pair<double, double>> gaps) {
  const double length = (b - a).norm();
  const Vec2 dir = (b - a) / length;
  std::sort(gaps.begin(), gaps.end());
  double start = 0.0;
  auto emit = [&](double s0, double s1) {
    if (s1 - s0 > 1e-6) plan.walls.push_back({a + s0 * dir, a + s1 * dir, thickness, material});
  };
  for (const auto& [center, width] : gaps) {
    emit(start, center - 0.5 * width);
    start = center + 0.5 * width;
  }
  emit(start, length);
}

void checkSplits(const std::vector<double>& splits, double size_x, const char* name, double min_width) {
  if (splits.size() < 2 || splits.front() != 0.0 || splits.back() != size_x) {
    invalid(std::string("CorridorLayout.") + name + " must start at 0 and end at size_m.x");
  }
  for (std::size_t i = 1; i < splits.size(); ++i) {
    if (!(splits[i] - splits[i - 1] >= min_width)) {
      invalid(std::string("CorridorLayout.") + name + ": room " + std::to_string(i) + " is narrower than " +
              std::to_string(min_width) + " m");
    }
  }
}

bool boxesOverlap(const Vec2& a_min, const Vec2& a_max, const Vec2& b_min, const Vec2& b_max, double gap) {
  return a_min.x() < b_max.x() + gap && b_min.x() < a_max.x() + gap && a_min.y() < b_max.y() + gap &&
         b_min.y() < a_max.y() + gap;
}

/// Does the 3D segment p_a-p_b pass through the box (slab test)?
bool segmentHitsBox(const Eigen::Vector3d& p_a, const Eigen::Vector3d& p_b, const Obstacle& box) {
  const Eigen::Vector3d lo(box.min_w.x(), box.min_w.y(), 0.0);
  const Eigen::Vector3d hi(box.max_w.x(), box.max_w.y(), box.height_m);
  const Eigen::Vector3d d = p_b - p_a;
  double t0 = 0.0, t1 = 1.0;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d(i)) < 1e-12) {
      if (p_a(i) < lo(i) || p_a(i) > hi(i)) return false;
      continue;
    }
    double ta = (lo(i) - p_a(i)) / d(i);
    double tb = (hi(i) - p_a(i)) / d(i);
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

double pointSegmentDistance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

}  // namespace

int OfficePlan::spaceAt(const Vec2& p_w) const {
  for (std::size_t i = 0; i < spaces.size(); ++i) {
    if (spaces[i].contains(p_w)) return static_cast<int>(i);
  }
  return -1;
}

std::vector<int> OfficePlan::doorsOf(int space) const {
  std::vector<int> out;
  for (std::size_t i = 0; i < doors.size(); ++i) {
    if (doors[i].space_a == space || doors[i].space_b == space) out.push_back(static_cast<int>(i));
  }
  return out;
}

Vec2 OfficePlan::approachPoint(int door, int space) const {
  const Space& s = spaces.at(static_cast<std::size_t>(space));
  const Vec2 c = doors.at(static_cast<std::size_t>(door)).center_w;
  return c.cwiseMax(s.free_min_w).cwiseMin(s.free_max_w);
}

bool segmentsIntersect(const Vec2& a0, const Vec2& a1, const Vec2& b0, const Vec2& b1) {
  const Vec2 da = a1 - a0, db = b1 - b0;
  const double d1 = cross2(db, a0 - b0), d2 = cross2(db, a1 - b0);
  const double d3 = cross2(da, b0 - a0), d4 = cross2(da, b1 - a0);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  // Touching or collinear: an end point on the other segment.
  auto onSegment = [](const Vec2& p, const Vec2& q0, const Vec2& q1) {
    return std::abs(cross2(q1 - q0, p - q0)) <= 1e-12 * std::max(1.0, (q1 - q0).squaredNorm()) &&
           p.x() >= std::min(q0.x(), q1.x()) - 1e-12 && p.x() <= std::max(q0.x(), q1.x()) + 1e-12 &&
           p.y() >= std::min(q0.y(), q1.y()) - 1e-12 && p.y() <= std::max(q0.y(), q1.y()) + 1e-12;
  };
  return onSegment(a0, b0, b1) || onSegment(a1, b0, b1) || onSegment(b0, a0, a1) || onSegment(b1, a0, a1);
}

OfficePlan buildCorridorPlan(const CorridorLayout& L) {
  const double W = L.size_m.x(), H = L.size_m.y();
  if (!(W > 0.0 && H > 0.0)) invalid("CorridorLayout.size_m must be positive");
  if (!(L.ceiling_m > 2.0)) invalid("CorridorLayout.ceiling_m must exceed 2 m");
  if (!(L.room_margin_m > 0.5 * L.door_width_m + 0.3)) invalid("CorridorLayout.room_margin_m is too small for the doors");
  if (!(L.corridor_margin_m >= 0.5)) invalid("CorridorLayout.corridor_margin_m must be at least 0.5 m");
  const double min_room = 2.0 * L.room_margin_m + 0.5;
  if (!(L.corridor_y0 >= min_room)) invalid("CorridorLayout.corridor_y0: south rooms too shallow");
  if (!(H - L.corridor_y1 >= min_room)) invalid("CorridorLayout.corridor_y1: north rooms too shallow");
  if (!(L.corridor_y1 - L.corridor_y0 > 2.0 * L.corridor_margin_m)) invalid("CorridorLayout: corridor too narrow");
  checkSplits(L.south_splits, W, "south_splits", min_room);
  checkSplits(L.north_splits, W, "north_splits", min_room);
  if (L.south_door_x.size() + 1 != L.south_splits.size()) invalid("CorridorLayout.south_door_x: one per south room");
  if (L.north_door_x.size() + 1 != L.north_splits.size()) invalid("CorridorLayout.north_door_x: one per north room");
  if (L.south_walls.size() + 2 != L.south_splits.size()) invalid("CorridorLayout.south_walls: one per interior split");
  if (L.north_walls.size() + 2 != L.north_splits.size()) invalid("CorridorLayout.north_walls: one per interior split");

  OfficePlan plan;
  plan.size_m = L.size_m;
  plan.ceiling_m = L.ceiling_m;

  Space corridor;
  corridor.name = "corridor";
  corridor.corridor = true;
  corridor.min_w = Vec2(0.0, L.corridor_y0);
  corridor.max_w = Vec2(W, L.corridor_y1);
  corridor.free_min_w = corridor.min_w + Vec2(L.room_margin_m, L.corridor_margin_m);
  corridor.free_max_w = corridor.max_w - Vec2(L.room_margin_m, L.corridor_margin_m);
  plan.spaces.push_back(corridor);

  auto addRooms = [&](bool north) {
    const std::vector<double>& splits = north ? L.north_splits : L.south_splits;
    const std::vector<double>& door_x = north ? L.north_door_x : L.south_door_x;
    const double y0 = north ? L.corridor_y1 : 0.0, y1 = north ? H : L.corridor_y0;
    std::vector<std::pair<double, double>> gaps;
    for (std::size_t i = 0; i + 1 < splits.size(); ++i) {
      Space room;
      room.name.assign(1, north ? 'N' : 'S');
      room.name += std::to_string(i + 1);
      room.min_w = Vec2(splits[i], y0);
      room.max_w = Vec2(splits[i + 1], y1);
      room.free_min_w = room.min_w + Vec2::Constant(L.room_margin_m);
      room.free_max_w = room.max_w - Vec2::Constant(L.room_margin_m);
      if (!(door_x[i] >= room.free_min_w.x() && door_x[i] <= room.free_max_w.x())) {
        invalid("CorridorLayout door of room " + room.name + " must be at least room_margin_m from its corners");
      }
      plan.spaces.push_back(room);
      Door d;
      d.center_w = Vec2(door_x[i], north ? L.corridor_y1 : L.corridor_y0);
      d.normal_w = north ? Vec2(0.0, -1.0) : Vec2(0.0, 1.0);  // room -> corridor
      d.width_m = L.door_width_m;
      d.space_a = static_cast<int>(plan.spaces.size()) - 1;
      d.space_b = 0;
      plan.doors.push_back(d);
      gaps.emplace_back(door_x[i], L.door_width_m);
    }
    const double y_wall = north ? L.corridor_y1 : L.corridor_y0;
    addWallWithGaps(plan, Vec2(0.0, y_wall), Vec2(W, y_wall), L.drywall_thickness_m, WallMaterial::kDrywall, gaps);
  };
  addRooms(false);
  const int first_north = static_cast<int>(plan.spaces.size());
  addRooms(true);

  // Walls between rooms, with their side doors.
  auto addInterior = [&](bool north) {
    const std::vector<double>& splits = north ? L.north_splits : L.south_splits;
    const std::vector<WallMaterial>& mats = north ? L.north_walls : L.south_walls;
    const double y0 = north ? L.corridor_y1 : 0.0, y1 = north ? H : L.corridor_y0;
    const int base = north ? first_north : 1;
    for (std::size_t i = 1; i + 1 < splits.size(); ++i) {
      std::vector<std::pair<double, double>> gaps;
      for (const CorridorLayout::SideDoor& sd : L.side_doors) {
        if (sd.north != north || sd.split != static_cast<int>(i)) continue;
        if (!(sd.y >= y0 + L.room_margin_m && sd.y <= y1 - L.room_margin_m)) {
          invalid("CorridorLayout.side_doors: door y must be at least room_margin_m from the room corners");
        }
        Door d;
        d.center_w = Vec2(splits[i], sd.y);
        d.normal_w = Vec2(1.0, 0.0);
        d.width_m = L.door_width_m;
        d.space_a = base + static_cast<int>(i) - 1;
        d.space_b = base + static_cast<int>(i);
        plan.doors.push_back(d);
        gaps.emplace_back(sd.y - y0, L.door_width_m);
      }
      const WallMaterial m = mats[i - 1];
      addWallWithGaps(plan, Vec2(splits[i], y0), Vec2(splits[i], y1),
                      m == WallMaterial::kConcrete ? L.concrete_thickness_m : L.drywall_thickness_m, m, gaps);
    }
  };
  for (const CorridorLayout::SideDoor& sd : L.side_doors) {
    const std::size_t n = (sd.north ? L.north_splits : L.south_splits).size();
    if (sd.split < 1 || static_cast<std::size_t>(sd.split) + 1 >= n) invalid("CorridorLayout.side_doors: split out of range");
  }
  addInterior(false);
  addInterior(true);

  // Exterior, concrete, no doors (the walk stays on this floor).
  const Vec2 c00(0.0, 0.0), c10(W, 0.0), c11(W, H), c01(0.0, H);
  for (const auto& [a, b] : {std::pair{c00, c10}, std::pair{c10, c11}, std::pair{c11, c01}, std::pair{c01, c00}}) {
    plan.walls.push_back({a, b, L.exterior_thickness_m, WallMaterial::kConcrete});
  }
  return plan;
}

void furnish(OfficePlan& plan, std::uint64_t seed, const FurnishParams& params) {
  SimRng rng(seed);
  constexpr double kWallInset = 0.16;  // from the centreline: clears the thickest wall (0.3 m)
  for (std::size_t si = 0; si < plan.spaces.size(); ++si) {
    const Space& room = plan.spaces[si];
    if (room.corridor) continue;
    // Keep-out zones: in front of every door of the room, both sides.
    std::vector<std::pair<Vec2, Vec2>> keep_out;
    for (int di : plan.doorsOf(static_cast<int>(si))) {
      const Door& d = plan.doors[static_cast<std::size_t>(di)];
      const Vec2 along(std::abs(d.normal_w.y()), std::abs(d.normal_w.x()));
      const Vec2 half = along * (0.5 * d.width_m + 0.3) + d.normal_w.cwiseAbs() * 1.2;
      keep_out.emplace_back(d.center_w - half, d.center_w + half);
    }
    auto fits = [&](const Vec2& lo, const Vec2& hi) {
      // Inside the strip between the walls and the free rectangle.
      if ((lo.array() < room.min_w.array() + kWallInset - 1e-9).any()) return false;
      if ((hi.array() > room.max_w.array() - kWallInset + 1e-9).any()) return false;
      if (boxesOverlap(lo, hi, room.free_min_w, room.free_max_w, 0.0)) return false;
      for (const auto& [ko_lo, ko_hi] : keep_out) {
        if (boxesOverlap(lo, hi, ko_lo, ko_hi, 0.0)) return false;
      }
      for (const Obstacle& o : plan.obstacles) {
        if (boxesOverlap(lo, hi, o.min_w, o.max_w, 0.05)) return false;
      }
      return true;
    };
    // A box of `length` along a random wall and `depth` into the room.
    auto place = [&](double length, double depth, double height, ObstacleKind kind) -> bool {
      for (int attempt = 0; attempt < 40; ++attempt) {
        const std::size_t side = rng.index(4);  // 0 south, 1 east, 2 north, 3 west
        const bool along_x = side == 0 || side == 2;
        const double span_lo = (along_x ? room.min_w.x() : room.min_w.y()) + kWallInset;
        const double span_hi = (along_x ? room.max_w.x() : room.max_w.y()) - kWallInset;
        if (span_hi - span_lo < length) continue;
        const double u = rng.uniform(span_lo, span_hi - length);
        Vec2 lo, hi;
        if (along_x) {
          const double y = side == 0 ? room.min_w.y() + kWallInset : room.max_w.y() - kWallInset - depth;
          lo = Vec2(u, y);
          hi = Vec2(u + length, y + depth);
        } else {
          const double x = side == 3 ? room.min_w.x() + kWallInset : room.max_w.x() - kWallInset - depth;
          lo = Vec2(x, u);
          hi = Vec2(x + depth, u + length);
        }
        if (!fits(lo, hi)) continue;
        plan.obstacles.push_back({lo, hi, height, kind});
        return true;
      }
      return false;
    };
    const int desks = 1 + static_cast<int>(rng.index(static_cast<std::size_t>(std::max(1, params.max_desks_per_room))));
    for (int k = 0; k < desks; ++k) {
      if (place(1.4, 0.7, 0.75, ObstacleKind::kDesk) && rng.bernoulli(params.seated_person_probability)) {
        place(0.5, 0.5, 1.3, ObstacleKind::kPerson);  // seated, beside the desk
      }
    }
    if (rng.bernoulli(params.cabinet_probability)) place(0.9, 0.45, 1.9, ObstacleKind::kCabinet);
    if (rng.bernoulli(params.standing_person_probability)) place(0.45, 0.4, 1.75, ObstacleKind::kPerson);
  }
}

OfficePlan defaultOfficePlan() {
  OfficePlan plan = buildCorridorPlan(CorridorLayout{});
  furnish(plan, 0xdefa017ULL);
  return plan;
}

OfficePlan randomOfficePlan(std::uint64_t seed) {
  SimRng rng(streamSeed(seed, 0x91a4));
  CorridorLayout L;
  const double W = rng.uniform(16.0, 28.0), H = rng.uniform(10.0, 16.0);
  const double corridor_w = rng.uniform(1.8, 2.4);
  const double south_depth = rng.uniform(3.5, H - corridor_w - 3.5);
  L.size_m = Vec2(W, H);
  L.corridor_y0 = south_depth;
  L.corridor_y1 = south_depth + corridor_w;
  L.side_doors.clear();
  auto rooms = [&](std::vector<double>& splits, std::vector<double>& door_x, std::vector<WallMaterial>& mats,
                   bool north) {
    splits = {0.0};
    double x = 0.0;
    while (W - x > 7.0) {
      x += rng.uniform(3.5, std::min(7.0, W - x - 3.5));
      splits.push_back(x);
    }
    splits.push_back(W);
    door_x.clear();
    mats.clear();
    for (std::size_t i = 0; i + 1 < splits.size(); ++i) {
      door_x.push_back(rng.uniform(splits[i] + L.room_margin_m, splits[i + 1] - L.room_margin_m));
    }
    const double y0 = north ? L.corridor_y1 : 0.0, y1 = north ? H : L.corridor_y0;
    for (std::size_t i = 1; i + 1 < splits.size(); ++i) {
      mats.push_back(rng.bernoulli(0.25) ? WallMaterial::kConcrete : WallMaterial::kDrywall);
      if (rng.bernoulli(0.3)) {
        L.side_doors.push_back({north, static_cast<int>(i), rng.uniform(y0 + L.room_margin_m, y1 - L.room_margin_m)});
      }
    }
  };
  rooms(L.south_splits, L.south_door_x, L.south_walls, false);
  rooms(L.north_splits, L.north_door_x, L.north_walls, true);
  OfficePlan plan = buildCorridorPlan(L);
  furnish(plan, streamSeed(seed, 0xf0a1));
  return plan;
}

std::vector<Eigen::Vector3d> placeAnchors(const OfficePlan& plan, const AnchorPlacement& placement) {
  if (placement.count < 1) invalid("AnchorPlacement.count must be at least 1");
  if (!(placement.min_height_m > 0.0 && placement.min_height_m <= placement.max_height_m &&
        placement.max_height_m < plan.ceiling_m)) {
    invalid("AnchorPlacement: need 0 < min_height_m <= max_height_m < ceiling");
  }
  if (!(placement.wall_offset_m > 0.16 && placement.wall_offset_m < 1.0)) {
    invalid("AnchorPlacement.wall_offset_m must be in (0.16, 1) m");
  }
  struct Candidate {
    Vec2 p;
    int space;
    bool used = false;
  };
  std::vector<Candidate> candidates;
  const double o = placement.wall_offset_m;
  for (std::size_t si = 0; si < plan.spaces.size(); ++si) {
    const Space& s = plan.spaces[si];
    const Vec2 lo = s.min_w + Vec2::Constant(o), hi = s.max_w - Vec2::Constant(o);
    const Vec2 mid = 0.5 * (lo + hi);
    for (const Vec2& p : {Vec2(lo.x(), lo.y()), Vec2(hi.x(), lo.y()), Vec2(hi.x(), hi.y()), Vec2(lo.x(), hi.y()),
                          Vec2(mid.x(), lo.y()), Vec2(hi.x(), mid.y()), Vec2(mid.x(), hi.y()), Vec2(lo.x(), mid.y())}) {
      bool near_door = false;
      for (const Door& d : plan.doors) near_door = near_door || (p - d.center_w).norm() < 0.5 * d.width_m + 0.4;
      if (!near_door) candidates.push_back({p, static_cast<int>(si)});
    }
  }
  if (static_cast<std::size_t>(placement.count) > candidates.size()) {
    invalid("AnchorPlacement.count " + std::to_string(placement.count) + " exceeds the " +
            std::to_string(candidates.size()) + " mounting points of this plan");
  }
  std::vector<int> per_space(plan.spaces.size(), 0);
  std::vector<Vec2> chosen;
  const Vec2 centre = 0.5 * plan.size_m;
  for (int i = 0; i < placement.count; ++i) {
    int least = std::numeric_limits<int>::max();
    for (const Candidate& c : candidates) {
      if (!c.used) least = std::min(least, per_space[static_cast<std::size_t>(c.space)]);
    }
    double best_score = -1.0;
    std::size_t best = 0;
    for (std::size_t ci = 0; ci < candidates.size(); ++ci) {
      const Candidate& c = candidates[ci];
      if (c.used || per_space[static_cast<std::size_t>(c.space)] != least) continue;
      double score = std::numeric_limits<double>::infinity();
      for (const Vec2& q : chosen) score = std::min(score, (c.p - q).norm());
      if (chosen.empty()) score = (c.p - centre).norm();  // first: a corner of the building
      if (score > best_score + 1e-9) {
        best_score = score;
        best = ci;
      }
    }
    candidates[best].used = true;
    ++per_space[static_cast<std::size_t>(candidates[best].space)];
    chosen.push_back(candidates[best].p);
  }
  std::vector<double> heights;
  for (int i = 0; i < placement.count; ++i) {
    heights.push_back(placement.min_height_m + (placement.max_height_m - placement.min_height_m) *
                                                   (static_cast<double>(i) + 0.5) / static_cast<double>(placement.count));
  }
  SimRng rng(placement.seed);
  rng.shuffle(heights);
  std::vector<Eigen::Vector3d> anchors;
  for (std::size_t i = 0; i < chosen.size(); ++i) anchors.emplace_back(chosen[i].x(), chosen[i].y(), heights[i]);
  return anchors;
}

Obstruction obstruction(const OfficePlan& plan, const Eigen::Vector3d& p_a, const Eigen::Vector3d& p_b) {
  Obstruction o;
  const Vec2 a = p_a.head<2>(), b = p_b.head<2>();
  for (const Wall& w : plan.walls) {
    if (!segmentsIntersect(a, b, w.a_w, w.b_w)) continue;
    if (w.material == WallMaterial::kConcrete) {
      ++o.concrete;
    } else {
      ++o.drywall;
    }
  }
  for (const Obstacle& box : plan.obstacles) {
    if (!segmentHitsBox(p_a, p_b, box)) continue;
    switch (box.kind) {
      case ObstacleKind::kDesk: ++o.desks; break;
      case ObstacleKind::kCabinet: ++o.cabinets; break;
      case ObstacleKind::kPerson: ++o.people; break;
      case ObstacleKind::kPillar: ++o.pillars; break;
    }
  }
  return o;
}

double distanceToWalls(const OfficePlan& plan, const Vec2& p_w) {
  double d = std::numeric_limits<double>::infinity();
  for (const Wall& w : plan.walls) d = std::min(d, pointSegmentDistance(p_w, w.a_w, w.b_w) - 0.5 * w.thickness_m);
  return d;
}

}  // namespace rilo::sim
