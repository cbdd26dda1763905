// The open-hall plan of the office simulator (office_hall.h): one room with
// pillars, desk islands and shelves; anchors around the perimeter at
// alternating heights; ceiling beacons within reach everywhere; the walk
// stays in the hall and out of the furniture; and most UWB paths are in line
// of sight, unlike the office floor where the anchors are spread over rooms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "sim/office_hall.h"
#include "sim/office_scenario.h"
#include "sim/office_tdoa.h"
#include "sim/office_ultrasonic.h"
#include "sim/walk.h"

namespace rilo::sim {
namespace {

using Vec2 = Eigen::Vector2d;

/// Distance from p to the box [lo, hi] (0 inside).
double boxDistance(const Vec2& p, const Vec2& lo, const Vec2& hi) { return (p.cwiseMax(lo).cwiseMin(hi) - p).norm(); }

bool separated(const Obstacle& a, const Obstacle& b, double gap) {
  return a.min_w.x() >= b.max_w.x() + gap - 1e-9 || b.min_w.x() >= a.max_w.x() + gap - 1e-9 ||
         a.min_w.y() >= b.max_w.y() + gap - 1e-9 || b.min_w.y() >= a.max_w.y() + gap - 1e-9;
}

/// Arc length of p counterclockwise around the rectangle [lo, hi] from lo.
double perimeterArc(const Vec2& p, const Vec2& lo, const Vec2& hi) {
  const double a = hi.x() - lo.x(), b = hi.y() - lo.y();
  if (std::abs(p.y() - lo.y()) < 1e-9 && p.x() < hi.x() - 1e-9) return p.x() - lo.x();
  if (std::abs(p.x() - hi.x()) < 1e-9 && p.y() < hi.y() - 1e-9) return a + p.y() - lo.y();
  if (std::abs(p.y() - hi.y()) < 1e-9 && p.x() > lo.x() + 1e-9) return a + b + hi.x() - p.x();
  return 2.0 * a + b + hi.y() - p.y();
}

OfficeScenarioParams hallParams(std::uint64_t seed, double duration_s) {
  OfficeScenarioParams p;
  p.seed = seed;
  p.duration_s = duration_s;
  p.plan = OfficePlanKind::kHall;
  return p;
}

// ---- Plan ----------------------------------------------------------------------

TEST(HallPlan, OneOpenRoomWithPillarsDesksAndShelvesAnAisleApart) {
  const HallLayout L;
  const OfficePlan plan = buildHallPlan(L);
  EXPECT_EQ(plan.size_m, Vec2(16.0, 10.0));
  ASSERT_EQ(plan.spaces.size(), 1u);
  EXPECT_FALSE(plan.spaces[0].corridor);
  EXPECT_TRUE(plan.doors.empty());
  ASSERT_EQ(plan.walls.size(), 4u);  // the exterior only
  for (const Wall& w : plan.walls) EXPECT_EQ(w.material, WallMaterial::kConcrete);
  int count[4] = {0, 0, 0, 0};
  for (const Obstacle& o : plan.obstacles) ++count[static_cast<int>(o.kind)];
  EXPECT_EQ(count[static_cast<int>(ObstacleKind::kPillar)], 2);
  EXPECT_EQ(count[static_cast<int>(ObstacleKind::kDesk)], 3);
  EXPECT_EQ(count[static_cast<int>(ObstacleKind::kCabinet)], 2);
  for (std::size_t i = 0; i < plan.obstacles.size(); ++i) {
    const Obstacle& o = plan.obstacles[i];
    if (o.kind == ObstacleKind::kPillar) {
      EXPECT_EQ(o.height_m, plan.ceiling_m);
      EXPECT_NEAR(0.5 * (o.min_w.y() + o.max_w.y()), 5.0, 1e-12);  // on the long centre line
    } else {
      EXPECT_GE(o.min_w.minCoeff(), L.aisle_m - 1e-9);
      EXPECT_LE(o.max_w.x(), 16.0 - L.aisle_m + 1e-9);
      EXPECT_LE(o.max_w.y(), 10.0 - L.aisle_m + 1e-9);
    }
    // An aisle between islands; a seated person sits right beside their desks.
    for (std::size_t j = i + 1; j < plan.obstacles.size(); ++j) {
      const Obstacle& q = plan.obstacles[j];
      const bool person_at_desk = q.kind == ObstacleKind::kPerson && o.kind == ObstacleKind::kDesk &&
                                  separated(o, q, 0.0) && !separated(o, q, 0.1);
      if (!person_at_desk) {
        EXPECT_TRUE(separated(o, q, L.aisle_m)) << i << " and " << j;
      }
    }
  }
  // The same hall every time; another size is furnished too.
  const OfficePlan again = buildHallPlan(L);
  ASSERT_EQ(again.obstacles.size(), plan.obstacles.size());
  for (std::size_t i = 0; i < plan.obstacles.size(); ++i) EXPECT_EQ(again.obstacles[i].min_w, plan.obstacles[i].min_w);
  HallLayout big;
  big.size_m = Vec2(30.0, 20.0);
  EXPECT_GE(buildHallPlan(big).obstacles.size(), 7u);
}

TEST(HallPlan, InvalidLayoutsThrow) {
  HallLayout L;
  L.size_m = Vec2(3.0, 10.0);
  EXPECT_THROW(buildHallPlan(L), std::invalid_argument);
  L = HallLayout{};
  L.high_anchor_max_m = 3.2;  // above the ceiling
  EXPECT_THROW(buildHallPlan(L), std::invalid_argument);
  L = HallLayout{};
  L.low_anchor_max_m = 2.6;  // overlaps the high anchors
  EXPECT_THROW(buildHallPlan(L), std::invalid_argument);
  L = HallLayout{};
  L.aisle_m = 0.8;  // no passage between islands
  EXPECT_THROW(buildHallPlan(L), std::invalid_argument);
  L = HallLayout{};
  L.walk_margin_m = 5.0;
  EXPECT_THROW(buildHallPlan(L), std::invalid_argument);
  const OfficePlan plan = buildHallPlan();
  EXPECT_THROW(placeHallAnchors(plan, HallLayout{}, 0), std::invalid_argument);
  EXPECT_THROW(placeHallAnchors(plan, HallLayout{}, 8, 0.1), std::invalid_argument);
  EXPECT_THROW(placeHallAnchors(defaultOfficePlan(), HallLayout{}, 8), std::invalid_argument);
  OfficeScenarioParams p = hallParams(1, 10.0);
  p.hall.pillar_size_m = 0.0;
  EXPECT_THROW(simulateOffice(p), std::invalid_argument);
}

// ---- Anchors and beacons ---------------------------------------------------------

TEST(HallAnchors, AroundThePerimeterAtAlternatingLowAndHighHeights) {
  const HallLayout L;
  const OfficePlan plan = buildHallPlan(L);
  for (int count : {1, 3, 4, 5, 8, 12, 32}) {
    const std::vector<Vec3> anchors = placeHallAnchors(plan, L, count);
    ASSERT_EQ(anchors.size(), static_cast<std::size_t>(count));
    int low = 0, high = 0, corners = 0;
    for (std::size_t i = 0; i < anchors.size(); ++i) {
      const Vec3& a = anchors[i];
      // 0.25 m from the nearest wall centreline, inside the hall.
      const double to_wall = std::min({a.x(), a.y(), 16.0 - a.x(), 10.0 - a.y()});
      EXPECT_NEAR(to_wall, 0.25, 1e-9) << a.transpose();
      EXPECT_GT(distanceToWalls(plan, a.head<2>()), 0.05);
      const bool corner = std::abs(std::min(a.x(), 16.0 - a.x()) - 0.25) < 1e-9 &&
                          std::abs(std::min(a.y(), 10.0 - a.y()) - 0.25) < 1e-9;
      corners += corner ? 1 : 0;
      // In order around the perimeter: low, high, low, ...
      const bool is_low = i % 2 == 0;
      if (is_low) {
        ++low;
        EXPECT_GE(a.z(), L.low_anchor_min_m);
        EXPECT_LE(a.z(), L.low_anchor_max_m);
      } else {
        ++high;
        EXPECT_GE(a.z(), L.high_anchor_min_m);
        EXPECT_LE(a.z(), L.high_anchor_max_m);
      }
      for (std::size_t j = 0; j < i; ++j) EXPECT_GT((anchors[j] - a).head<2>().norm(), 0.4) << count;
      for (const Obstacle& o : plan.obstacles) EXPECT_GT(boxDistance(a.head<2>(), o.min_w, o.max_w), 1.0);
    }
    EXPECT_EQ(corners, std::min(count, 4)) << count;
    EXPECT_EQ(low - high, count % 2);
    // Counterclockwise from the south-west corner: the arc length around the perimeter increases.
    double prev = -1.0;
    for (const Vec3& a : anchors) {
      const double s = perimeterArc(a.head<2>(), Vec2::Constant(0.25), Vec2(15.75, 9.75));
      EXPECT_GT(s, prev) << count;
      prev = s;
    }
  }
  // The default eight: the four corners low, the four side middles high.
  const std::vector<Vec3> eight = placeHallAnchors(plan, L, 8);
  EXPECT_EQ(eight[0], Vec3(0.25, 0.25, 0.5 + 0.5 * 0.125));
  EXPECT_NEAR(eight[1].x(), 8.0, 1e-9);
  EXPECT_EQ(placeHallAnchors(plan, L, 8), eight);  // deterministic
}

TEST(HallUltrasonic, CeilingBeaconsWithinReachEverywhereOnTheFloor) {
  const OfficePlan plan = buildHallPlan();
  UltrasonicParams up;
  const std::vector<Vec3> beacons = placeHallUltrasonicBeacons(plan, up);
  ASSERT_EQ(beacons.size(), 4u);
  const Space& hall = plan.spaces[0];
  for (const Vec3& b : beacons) {
    EXPECT_DOUBLE_EQ(b.z(), plan.ceiling_m - up.mount_below_ceiling_m);
    EXPECT_TRUE(hall.inFree(b.head<2>()));
    for (const Obstacle& o : plan.obstacles) {
      if (o.kind == ObstacleKind::kPillar) {
        EXPECT_GT(boxDistance(b.head<2>(), o.min_w, o.max_w), 0.25);
      }
    }
  }
  // Receiver at ~1.4 m anywhere in the free rectangle: at least two beacons in range.
  for (double x = hall.free_min_w.x(); x <= hall.free_max_w.x() + 1e-9; x += 0.5) {
    for (double y = hall.free_min_w.y(); y <= hall.free_max_w.y() + 1e-9; y += 0.5) {
      int in_range = 0;
      for (const Vec3& b : beacons) in_range += (b - Vec3(x, y, 1.4)).norm() <= up.max_range_m ? 1 : 0;
      EXPECT_GE(in_range, 2) << x << ", " << y;
    }
  }
  // Other counts fill a grid; a beacon on a pillar moves off it.
  for (int n : {1, 2, 5, 9}) {
    up.beacons = n;
    up.ping_rate_hz = 2.0;
    const std::vector<Vec3> grid = placeHallUltrasonicBeacons(plan, up);
    ASSERT_EQ(grid.size(), static_cast<std::size_t>(n));
    for (const Vec3& b : grid) {
      EXPECT_TRUE(hall.inFree(b.head<2>()));
      for (const Obstacle& o : plan.obstacles) {
        if (o.kind == ObstacleKind::kPillar) {
          EXPECT_GT(boxDistance(b.head<2>(), o.min_w, o.max_w), 0.25) << n;
        }
      }
    }
  }
}

// ---- Walk --------------------------------------------------------------------------

TEST(HallWalk, StaysInsideTheHallAndOutOfTheFurniture) {
  const OfficePlan plan = buildHallPlan();
  const Space& hall = plan.spaces[0];
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    WalkParams wp;
    wp.seed = seed;
    wp.duration_s = 400.0;
    wp.start_moving = seed % 2 == 0;
    const OfficeWalk walk(plan, wp);
    double nearest_furniture = 1e9;
    Vec2 lo = Vec2::Constant(1e9), hi = Vec2::Constant(-1e9);
    double travelled = 0.0;
    Vec2 prev = walk.at(0.0).T_w_b.p.head<2>();
    for (double t = 0.0; t <= wp.duration_s; t += 0.05) {
      const Vec3 p = walk.at(t).T_w_b.p;
      const Vec2 xy = p.head<2>();
      ASSERT_TRUE(hall.inFree(xy, 0.05)) << "left the walking area at t=" << t << " p=" << xy.transpose();
      ASSERT_GT(distanceToWalls(plan, xy), 0.5) << "t=" << t;
      for (const Obstacle& o : plan.obstacles) {
        const double d = boxDistance(xy, o.min_w, o.max_w);
        ASSERT_GT(d, 0.25) << "walked into furniture at t=" << t << " p=" << xy.transpose();
        nearest_furniture = std::min(nearest_furniture, d);
      }
      lo = lo.cwiseMin(xy);
      hi = hi.cwiseMax(xy);
      travelled += (xy - prev).norm();
      prev = xy;
    }
    EXPECT_LT(nearest_furniture, 1.0) << "walks past the furniture, not only far from it";
    EXPECT_GT((hi - lo).x(), 11.0) << "covers the hall, seed " << seed;
    EXPECT_GT((hi - lo).y(), 6.0);
    EXPECT_GT(travelled, 150.0);
    if (wp.start_moving) {
      EXPECT_GT(walk.at(0.0).v_w.head<2>().norm(), 0.7);
    }
  }
}

TEST(HallWalk, AnEmptyHallAndAFurnishedOneWalkTheSameWithoutIslands) {
  // Without furniture inside the free rectangle the walk draws as it always
  // did: the same route as in a plan whose furniture keeps to the wall strip.
  HallLayout bare;
  bare.pillars = 0;
  bare.desk_islands = 0;
  bare.shelves = 0;
  const OfficePlan empty = buildHallPlan(bare);
  OfficePlan strip = empty;
  strip.obstacles.push_back({Vec2(0.2, 0.2), Vec2(0.6, 2.0), 1.9, ObstacleKind::kCabinet});  // beside, not inside
  WalkParams wp;
  wp.seed = 11;
  wp.duration_s = 120.0;
  EXPECT_EQ(OfficeWalk(empty, wp).route(), OfficeWalk(strip, wp).route());
  OfficePlan island = empty;
  island.obstacles.push_back({Vec2(7.0, 4.0), Vec2(9.0, 6.0), 0.75, ObstacleKind::kDesk});
  EXPECT_NE(OfficeWalk(empty, wp).route(), OfficeWalk(island, wp).route());
}

// ---- Line of sight: hall vs office ---------------------------------------------------

struct LosCounts {
  double twr_nlos = 0.0, tdoa_nlos = 0.0, ultrasonic_reflected = 0.0, ultrasonic_per_ping = 0.0;
};

LosCounts measure(OfficeScenarioParams p) {
  p.ultrasonic.enabled = true;
  const OfficeSimulation sim = simulateOffice(p);
  LosCounts c;
  c.twr_nlos = sim.stats.nlosFraction();
  OfficeTdoaStream tdoa(p, sim.setup);
  TdoaSample ts;
  TdoaTruth tt;
  while (tdoa.next(ts, tt)) {
  }
  c.tdoa_nlos = tdoa.stats().nlosFraction();
  OfficeUltrasonicStream us(p, sim.setup);
  UltrasonicSample u;
  UltrasonicTruth ut;
  while (us.next(u, ut)) {
  }
  c.ultrasonic_reflected = us.stats().nlosFraction();
  c.ultrasonic_per_ping = static_cast<double>(us.stats().measurements) / static_cast<double>(us.stats().pings);
  return c;
}

TEST(HallScenario, MostPathsAreInLineOfSightUnlikeTheOffice) {
  // Two minutes of the same seed in the hall and on the default office floor.
  OfficeScenarioParams office = hallParams(1, 120.0);
  office.plan = OfficePlanKind::kDefault;
  const LosCounts h = measure(hallParams(1, 120.0)), o = measure(office);
  std::printf("[ NLOS     ] hall: TWR %.1f%%, TDoA %.1f%%, ultrasonic reflected %.1f%% (%.0f%% of pings ranged); "
              "office: TWR %.1f%%, TDoA %.1f%%, ultrasonic reflected %.1f%% (%.0f%% of pings ranged)\n",
              100.0 * h.twr_nlos, 100.0 * h.tdoa_nlos, 100.0 * h.ultrasonic_reflected, 100.0 * h.ultrasonic_per_ping,
              100.0 * o.twr_nlos, 100.0 * o.tdoa_nlos, 100.0 * o.ultrasonic_reflected, 100.0 * o.ultrasonic_per_ping);
  // The wearer's body still blocks the anchors behind them (~a third of the
  // paths), so the hall is not all LOS: a TDoA row needs two clear paths.
  EXPECT_GT(h.twr_nlos, 0.05);
  EXPECT_LT(h.twr_nlos, 0.40);
  EXPECT_GT(o.twr_nlos, 0.60);
  EXPECT_LT(h.twr_nlos, 0.5 * o.twr_nlos);
  EXPECT_LT(h.tdoa_nlos, 0.80);
  EXPECT_GT(o.tdoa_nlos, 0.90);
  EXPECT_GT(1.0 - h.tdoa_nlos, 5.0 * (1.0 - o.tdoa_nlos));  // LOS rows: several times as many
  // Ultrasonic: no walls in the way, so far more pings give a range.
  EXPECT_GT(h.ultrasonic_per_ping, 2.0 * o.ultrasonic_per_ping);
  EXPECT_LT(h.ultrasonic_reflected, 0.35);
}

TEST(HallScenario, DeterministicPerSeedAndTheSameHallForEverySeed) {
  const OfficeSimulation a = simulateOffice(hallParams(5, 20.0)), b = simulateOffice(hallParams(5, 20.0));
  ASSERT_EQ(a.scenario.ranges.size(), b.scenario.ranges.size());
  for (std::size_t i = 0; i < a.scenario.ranges.size(); ++i) {
    ASSERT_EQ(a.scenario.ranges[i].t_ns, b.scenario.ranges[i].t_ns);
    ASSERT_EQ(a.scenario.ranges[i].range_m, b.scenario.ranges[i].range_m);
  }
  ASSERT_EQ(a.scenario.imu.size(), b.scenario.imu.size());
  EXPECT_EQ(a.scenario.imu.back().accel_m_s2, b.scenario.imu.back().accel_m_s2);
  const OfficeSimulation c = simulateOffice(hallParams(6, 20.0));
  EXPECT_EQ(c.scenario.p_w_anchors, a.scenario.p_w_anchors);  // the hall does not depend on the seed
  EXPECT_NE(c.setup.walk->route(), a.setup.walk->route());
  EXPECT_EQ(a.setup.plan->spaces.size(), 1u);
}

}  // namespace
}  // namespace rilo::sim
