#include "sim/office_hall.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "sim/office_random.h"

namespace rilo::sim {
namespace {

using Vec2 = Eigen::Vector2d;

constexpr double kDeskIslandM = 1.4;   // two 1.4 m x 0.7 m desks face to face
constexpr double kDeskHeightM = 0.75;
constexpr double kPersonM = 0.5;       // seated person beside a desk island
constexpr double kPersonHeightM = 1.3;
constexpr double kShelfLengthM = 2.0, kShelfDepthM = 0.5, kShelfHeightM = 2.0;
constexpr int kPlaceTries = 100;

void require(bool ok, const char* field, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("HallLayout.") + field + " " + what);
}

/// At least `gap` apart along x or along y.
bool separated(const Vec2& a_lo, const Vec2& a_hi, const Vec2& b_lo, const Vec2& b_hi, double gap) {
  return a_lo.x() >= b_hi.x() + gap || b_lo.x() >= a_hi.x() + gap || a_lo.y() >= b_hi.y() + gap ||
         b_lo.y() >= a_hi.y() + gap;
}

/// Point at arc length s counterclockwise around the rectangle [lo, hi] from lo.
Vec2 perimeterPoint(const Vec2& lo, const Vec2& hi, double s) {
  const double a = hi.x() - lo.x(), b = hi.y() - lo.y();
  if (s < a) return {lo.x() + s, lo.y()};
  if (s < a + b) return {hi.x(), lo.y() + (s - a)};
  if (s < 2.0 * a + b) return {hi.x() - (s - a - b), hi.y()};
  return {lo.x(), hi.y() - (s - 2.0 * a - b)};
}

}  // namespace

void validate(const HallLayout& L) {
  require(L.size_m.allFinite() && (L.size_m.array() >= 4.0).all() && (L.size_m.array() <= 200.0).all(), "size_m",
          "must be in [4, 200] m on both sides");
  require(std::isfinite(L.ceiling_m) && L.ceiling_m > 2.0 && L.ceiling_m <= 20.0, "ceiling_m", "must be in (2, 20] m");
  require(L.wall_thickness_m > 0.0 && L.wall_thickness_m <= 1.0, "wall_thickness_m", "must be in (0, 1] m");
  require(L.walk_margin_m >= 0.5 && L.walk_margin_m <= 0.5 * L.size_m.minCoeff() - 0.5, "walk_margin_m",
          "must be in [0.5 m, half the shorter side - 0.5 m]");
  require(L.pillars >= 0 && L.pillars <= 20, "pillars", "must be in [0, 20]");
  require(L.pillar_size_m >= 0.2 && L.pillar_size_m <= 2.0, "pillar_size_m", "must be in [0.2, 2] m");
  require(L.size_m.maxCoeff() / (L.pillars + 1) > L.pillar_size_m + 1.0, "pillars", "too many for the hall's length");
  require(L.desk_islands >= 0 && L.desk_islands <= 50, "desk_islands", "must be in [0, 50]");
  require(L.shelves >= 0 && L.shelves <= 50, "shelves", "must be in [0, 50]");
  require(L.seated_person_probability >= 0.0 && L.seated_person_probability <= 1.0, "seated_person_probability",
          "must be in [0, 1]");
  require(L.aisle_m >= 1.2 && L.aisle_m <= 10.0, "aisle_m", "must be in [1.2, 10] m");
  require(L.low_anchor_min_m > 0.0 && L.low_anchor_min_m <= L.low_anchor_max_m, "low_anchor_min_m",
          "must be in (0, low_anchor_max_m]");
  require(L.low_anchor_max_m < L.high_anchor_min_m, "low_anchor_max_m", "must be below high_anchor_min_m");
  require(L.high_anchor_min_m <= L.high_anchor_max_m && L.high_anchor_max_m < L.ceiling_m, "high_anchor_max_m",
          "must be in [high_anchor_min_m, ceiling_m)");
}

OfficePlan buildHallPlan(const HallLayout& L) {
  validate(L);
  OfficePlan plan;
  plan.size_m = L.size_m;
  plan.ceiling_m = L.ceiling_m;
  Space hall;
  hall.name = "hall";
  hall.min_w = Vec2::Zero();
  hall.max_w = L.size_m;
  hall.free_min_w = Vec2::Constant(L.walk_margin_m);
  hall.free_max_w = L.size_m - Vec2::Constant(L.walk_margin_m);
  plan.spaces.push_back(hall);
  const Vec2 c00(0.0, 0.0), c10(L.size_m.x(), 0.0), c11 = L.size_m, c01(0.0, L.size_m.y());
  for (const auto& [a, b] : {std::pair{c00, c10}, std::pair{c10, c11}, std::pair{c11, c01}, std::pair{c01, c00}}) {
    plan.walls.push_back({a, b, L.wall_thickness_m, WallMaterial::kConcrete});
  }

  const int axis = L.size_m.x() >= L.size_m.y() ? 0 : 1;
  for (int i = 0; i < L.pillars; ++i) {
    Vec2 c = 0.5 * L.size_m;
    c(axis) = L.size_m(axis) * static_cast<double>(i + 1) / static_cast<double>(L.pillars + 1);
    const Vec2 half = Vec2::Constant(0.5 * L.pillar_size_m);
    plan.obstacles.push_back({c - half, c + half, L.ceiling_m, ObstacleKind::kPillar});
  }

  // Islands: an aisle from the walls and from each other (axis-aligned boxes
  // that never touch: the floor around them stays connected).
  SimRng rng(L.furniture_seed);
  const Vec2 area_lo = Vec2::Constant(L.aisle_m);
  const Vec2 area_hi = L.size_m - Vec2::Constant(L.aisle_m);
  auto fits = [&](const Vec2& lo, const Vec2& hi, std::size_t ignore) {
    if ((lo.array() < area_lo.array()).any() || (hi.array() > area_hi.array()).any()) return false;
    for (std::size_t i = 0; i < plan.obstacles.size(); ++i) {
      const Obstacle& o = plan.obstacles[i];
      if (i != ignore && !separated(lo, hi, o.min_w, o.max_w, L.aisle_m)) return false;
    }
    return true;
  };
  auto place = [&](const Vec2& size, double height, ObstacleKind kind) -> bool {
    if (((area_hi - area_lo - size).array() < 0.0).any()) return false;
    for (int attempt = 0; attempt < kPlaceTries; ++attempt) {
      const Vec2 lo(rng.uniform(area_lo.x(), area_hi.x() - size.x()), rng.uniform(area_lo.y(), area_hi.y() - size.y()));
      if (!fits(lo, lo + size, plan.obstacles.size())) continue;
      plan.obstacles.push_back({lo, lo + size, height, kind});
      return true;
    }
    return false;
  };
  for (int k = 0; k < L.desk_islands; ++k) {
    if (!place(Vec2::Constant(kDeskIslandM), kDeskHeightM, ObstacleKind::kDesk)) continue;
    if (!rng.bernoulli(L.seated_person_probability)) continue;
    // Beside the middle of one side (a random one first), part of the island.
    const std::size_t island = plan.obstacles.size() - 1;
    const Vec2 lo = plan.obstacles[island].min_w, hi = plan.obstacles[island].max_w, mid = 0.5 * (lo + hi);
    const std::size_t first = rng.index(4);
    for (std::size_t j = 0; j < 4; ++j) {
      const std::size_t side = (first + j) % 4;  // 0 south, 1 east, 2 north, 3 west
      Vec2 p_lo = mid - Vec2::Constant(0.5 * kPersonM);
      if (side == 0) p_lo.y() = lo.y() - 0.05 - kPersonM;
      if (side == 1) p_lo.x() = hi.x() + 0.05;
      if (side == 2) p_lo.y() = hi.y() + 0.05;
      if (side == 3) p_lo.x() = lo.x() - 0.05 - kPersonM;
      const Vec2 p_hi = p_lo + Vec2::Constant(kPersonM);
      if (!fits(p_lo, p_hi, island)) continue;
      plan.obstacles.push_back({p_lo, p_hi, kPersonHeightM, ObstacleKind::kPerson});
      break;
    }
  }
  for (int k = 0; k < L.shelves; ++k) {
    const Vec2 size = rng.bernoulli(0.5) ? Vec2(kShelfLengthM, kShelfDepthM) : Vec2(kShelfDepthM, kShelfLengthM);
    place(size, kShelfHeightM, ObstacleKind::kCabinet);
  }
  return plan;
}

std::vector<Eigen::Vector3d> placeHallAnchors(const OfficePlan& plan, const HallLayout& L, int count,
                                              double wall_offset_m) {
  if (count < 1) throw std::invalid_argument("placeHallAnchors: count must be at least 1");
  if (!(wall_offset_m > 0.16 && wall_offset_m < 1.0)) {
    throw std::invalid_argument("placeHallAnchors: wall_offset_m must be in (0.16, 1) m");
  }
  if (plan.spaces.size() != 1) throw std::invalid_argument("placeHallAnchors: the plan must be one hall");
  validate(L);
  if (!(L.high_anchor_max_m < plan.ceiling_m)) {
    throw std::invalid_argument("placeHallAnchors: HallLayout.high_anchor_max_m must be below the plan's ceiling");
  }
  const Vec2 lo = Vec2::Constant(wall_offset_m), hi = plan.size_m - Vec2::Constant(wall_offset_m);
  const double a = hi.x() - lo.x(), b = hi.y() - lo.y();
  const std::array<double, 4> side_start{0.0, a, a + b, 2.0 * a + b}, side_length{a, b, a, b};
  std::vector<double> s;  // arc lengths around the perimeter
  if (count <= 4) {
    for (int k : {0, 2, 1, 3}) {
      if (static_cast<int>(s.size()) < count) s.push_back(side_start[static_cast<std::size_t>(k)]);
    }
  } else {
    s.assign(side_start.begin(), side_start.end());
    // The others: shares of the sides by length, largest remainders first.
    const int extra = count - 4;
    const double perimeter = 2.0 * (a + b);
    std::array<int, 4> n{};
    std::array<double, 4> remainder{};
    int given = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      const double quota = extra * side_length[k] / perimeter;
      n[k] = static_cast<int>(std::floor(quota));
      remainder[k] = quota - n[k];
      given += n[k];
    }
    std::array<std::size_t, 4> order{0, 1, 2, 3};
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t i, std::size_t j) { return remainder[i] > remainder[j]; });
    for (std::size_t k = 0; given < extra; ++k, ++given) ++n[order[k]];
    for (std::size_t k = 0; k < 4; ++k) {
      for (int j = 0; j < n[k]; ++j) s.push_back(side_start[k] + side_length[k] * (j + 1) / (n[k] + 1));
    }
  }
  std::sort(s.begin(), s.end());
  const int lows = (count + 1) / 2, highs = count / 2;
  std::vector<Eigen::Vector3d> anchors;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const bool low = i % 2 == 0;
    const double k = static_cast<double>(i / 2) + 0.5;
    const double z = low ? L.low_anchor_min_m + (L.low_anchor_max_m - L.low_anchor_min_m) * k / lows
                         : L.high_anchor_min_m + (L.high_anchor_max_m - L.high_anchor_min_m) * k / highs;
    const Vec2 p = perimeterPoint(lo, hi, s[i]);
    anchors.emplace_back(p.x(), p.y(), z);
  }
  return anchors;
}

std::vector<Eigen::Vector3d> placeHallUltrasonicBeacons(const OfficePlan& plan, const UltrasonicParams& params) {
  validate(params);
  if (plan.spaces.size() != 1) throw std::invalid_argument("placeHallUltrasonicBeacons: the plan must be one hall");
  const double z = plan.ceiling_m - params.mount_below_ceiling_m;
  if (!(z > 2.0)) {
    throw std::invalid_argument("placeHallUltrasonicBeacons: beacons would hang below 2 m (ceiling too low)");
  }
  const Space& hall = plan.spaces.front();
  const Vec2 size = hall.free_max_w - hall.free_min_w;
  const int m = params.beacons;
  const int rows0 = std::clamp(static_cast<int>(std::lround(std::sqrt(m * size.y() / size.x()))), 1, m);
  const int cols = (m + rows0 - 1) / rows0;
  const int rows = (m + cols - 1) / cols;
  std::vector<Eigen::Vector3d> beacons;
  for (int r = 0; r < rows; ++r) {
    const int in_row = std::min(cols, m - r * cols);
    for (int c = 0; c < in_row; ++c) {
      Vec2 p = hall.free_min_w + Vec2(size.x() * (c + 0.5) / in_row, size.y() * (r + 0.5) / rows);
      // Off a pillar (it reaches the ceiling): to the nearest side, 0.3 m clear.
      for (const Obstacle& o : plan.obstacles) {
        if (o.kind != ObstacleKind::kPillar) continue;
        const Vec2 lo = o.min_w - Vec2::Constant(0.3), hi = o.max_w + Vec2::Constant(0.3);
        if ((p.array() <= lo.array()).any() || (p.array() >= hi.array()).any()) continue;
        const std::array<double, 4> move{p.x() - lo.x(), hi.x() - p.x(), p.y() - lo.y(), hi.y() - p.y()};
        const auto k = static_cast<std::size_t>(std::min_element(move.begin(), move.end()) - move.begin());
        if (k == 0) p.x() = lo.x();
        if (k == 1) p.x() = hi.x();
        if (k == 2) p.y() = lo.y();
        if (k == 3) p.y() = hi.y();
      }
      beacons.emplace_back(p.x(), p.y(), z);
    }
  }
  return beacons;
}

}  // namespace rilo::sim
