// Office simulator: plan geometry, line of sight, the walk (stays on the
// floor, passes walls only through doors, exact derivatives, IMU consistent
// with the motion), the channel (NLOS longer and persistent) and the ranging
// (strongest-N selection, determinism per seed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "math/so3.h"
#include "sim/office.h"
#include "sim/office_channel.h"
#include "sim/office_scenario.h"
#include "sim/walk.h"

namespace rilo::sim {
namespace {

using Vec2 = Eigen::Vector2d;

KinematicState standingAt(const Vec3& p, double yaw) {
  KinematicState s;
  s.T_w_b = Pose3(Mat3(Eigen::AngleAxisd(yaw, Vec3::UnitZ())), p);
  s.v_w.setZero();
  s.a_w.setZero();
  s.omega_b.setZero();
  return s;
}

OfficeScenarioParams shortParams(std::uint64_t seed, double duration_s = 30.0) {
  OfficeScenarioParams p;
  p.seed = seed;
  p.duration_s = duration_s;
  return p;
}

// ---- Plan --------------------------------------------------------------------

TEST(OfficePlan, DefaultPlanHasCorridorRoomsDoorsAndSparseAnchors) {
  const OfficePlan plan = defaultOfficePlan();
  EXPECT_EQ(plan.size_m, Vec2(20.0, 12.0));
  ASSERT_EQ(plan.spaces.size(), 7u);
  EXPECT_TRUE(plan.spaces[0].corridor);
  EXPECT_EQ(plan.doors.size(), 7u);  // six room doors, one between two rooms
  int concrete = 0;
  for (const Wall& w : plan.walls) concrete += w.material == WallMaterial::kConcrete ? 1 : 0;
  EXPECT_EQ(concrete, 4 + 2);  // exterior and one interior wall on each side
  EXPECT_FALSE(plan.obstacles.empty());

  const std::vector<Vec3> anchors = placeAnchors(plan);
  ASSERT_EQ(anchors.size(), 8u);
  double z_min = 10.0, z_max = 0.0;
  std::set<int> spaces;
  for (const Vec3& a : anchors) {
    z_min = std::min(z_min, a.z());
    z_max = std::max(z_max, a.z());
    EXPECT_GE(a.z(), 2.0);
    EXPECT_LE(a.z(), 2.8);
    EXPECT_GT(distanceToWalls(plan, a.head<2>()), 0.05) << a.transpose();
    const int s = plan.spaceAt(a.head<2>());
    EXPECT_GE(s, 0);
    spaces.insert(s);
  }
  EXPECT_GT(z_max - z_min, 0.5);          // never all at one height
  EXPECT_EQ(spaces.size(), 7u);           // every space has an anchor before any gets two
  EXPECT_EQ(placeAnchors(plan), anchors);  // deterministic
  AnchorPlacement four;
  four.count = 4;
  EXPECT_EQ(placeAnchors(plan, four).size(), 4u);
}

TEST(OfficePlan, RandomPlansAreDeterministicAndConsistent) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const OfficePlan a = randomOfficePlan(seed), b = randomOfficePlan(seed);
    ASSERT_EQ(a.walls.size(), b.walls.size());
    for (std::size_t i = 0; i < a.walls.size(); ++i) EXPECT_EQ(a.walls[i].a_w, b.walls[i].a_w);
    ASSERT_EQ(a.obstacles.size(), b.obstacles.size());
    EXPECT_GE(a.size_m.x(), 16.0);
    EXPECT_LE(a.size_m.x(), 28.0);
    for (const Space& s : a.spaces) {
      EXPECT_TRUE((s.free_min_w.array() < s.free_max_w.array()).all()) << s.name;
      EXPECT_TRUE(s.contains(s.free_min_w) && s.contains(s.free_max_w)) << s.name;
    }
    // Furniture stands in the strip along the walls, never in a free rectangle.
    for (const Obstacle& o : a.obstacles) {
      const Vec2 c = 0.5 * (o.min_w + o.max_w);
      const int s = a.spaceAt(c);
      ASSERT_GE(s, 0);
      const Space& sp = a.spaces[static_cast<std::size_t>(s)];
      const bool overlaps = o.min_w.x() < sp.free_max_w.x() && sp.free_min_w.x() < o.max_w.x() &&
                            o.min_w.y() < sp.free_max_w.y() && sp.free_min_w.y() < o.max_w.y();
      EXPECT_FALSE(overlaps);
      EXPECT_GT(distanceToWalls(a, c), 0.0);
    }
    EXPECT_EQ(placeAnchors(a).size(), 8u);
    EXPECT_NE(randomOfficePlan(seed + 100).size_m, a.size_m);
  }
}

TEST(OfficePlan, InvalidLayoutsAndPlacementsThrow) {
  CorridorLayout L;
  L.south_door_x[0] = 0.5;  // too close to the corner
  EXPECT_THROW(buildCorridorPlan(L), std::invalid_argument);
  L = CorridorLayout{};
  L.south_splits = {0.0, 2.0, 20.0};  // a room narrower than its margins
  L.south_door_x = {1.0, 10.0};
  L.south_walls = {WallMaterial::kDrywall};
  EXPECT_THROW(buildCorridorPlan(L), std::invalid_argument);
  AnchorPlacement bad;
  bad.count = 0;
  EXPECT_THROW(placeAnchors(defaultOfficePlan(), bad), std::invalid_argument);
  bad.count = 1000;
  EXPECT_THROW(placeAnchors(defaultOfficePlan(), bad), std::invalid_argument);
  bad = AnchorPlacement{};
  bad.max_height_m = 3.5;  // above the ceiling
  EXPECT_THROW(placeAnchors(defaultOfficePlan(), bad), std::invalid_argument);
}

// ---- Line of sight -------------------------------------------------------------

TEST(LineOfSight, CountsWallsByMaterialAndDoorsAreGaps) {
  const OfficePlan plan = defaultOfficePlan();
  // S1 = [0,7] x [0,5], S2 = [7,14] x [0,5] (concrete between), corridor y in [5,7].
  const Vec3 in_s1(3.5, 2.5, 1.3), in_s2(10.5, 2.5, 2.5), in_corridor(5.5, 6.0, 2.5);
  EXPECT_TRUE(obstruction(plan, in_s1, Vec3(0.25, 0.25, 2.5)).walls() == 0);
  const Obstruction through_concrete = obstruction(plan, in_s1, in_s2);
  EXPECT_EQ(through_concrete.concrete, 1);
  EXPECT_EQ(through_concrete.drywall, 0);
  // Straight through the S1 door (x = 5.5) into the corridor, and beside it.
  EXPECT_EQ(obstruction(plan, Vec3(5.5, 3.0, 1.3), in_corridor).walls(), 0);
  EXPECT_EQ(obstruction(plan, Vec3(3.0, 3.0, 1.3), Vec3(3.0, 6.0, 2.5)).drywall, 1);
  // S1 -> N1 across the corridor: two drywalls.
  EXPECT_EQ(obstruction(plan, Vec3(3.0, 3.0, 1.3), Vec3(3.0, 9.0, 2.5)).drywall, 2);
  // Boxes are 3D: through a box at its height, not above it.
  OfficePlan boxed = plan;
  boxed.obstacles = {{Vec2(2.0, 2.0), Vec2(3.0, 3.0), 1.9, ObstacleKind::kCabinet}};
  EXPECT_EQ(obstruction(boxed, Vec3(1.0, 2.5, 1.0), Vec3(4.0, 2.5, 1.0)).cabinets, 1);
  EXPECT_EQ(obstruction(boxed, Vec3(1.0, 2.5, 2.2), Vec3(4.0, 2.5, 2.2)).cabinets, 0);
  EXPECT_TRUE(obstruction(boxed, Vec3(1.0, 2.5, 2.2), Vec3(4.0, 2.5, 2.2)).lineOfSight());
}

TEST(OfficeChannel, ARangeThroughAWallIsNlosLongerAndWeaker) {
  OfficePlan plan = defaultOfficePlan();
  plan.obstacles.clear();
  // Two anchors 4.5 m from the tag: one in the same room, one behind the concrete wall.
  const Vec3 p_tag(5.0, 2.5, 1.3);
  const std::vector<Vec3> anchors{Vec3(0.5, 2.5, 1.3), Vec3(9.5, 2.5, 1.3)};
  ChannelParams cp;
  cp.body_shadowing = false;
  const OfficeChannel channel(plan, anchors, Vec3::Zero(), cp, 42);
  const LinkState open = channel.link(0, standingAt(p_tag, 0.0));
  const LinkState wall = channel.link(1, standingAt(p_tag, 0.0));
  EXPECT_TRUE(open.los);
  EXPECT_EQ(open.excess_m, 0.0);
  EXPECT_NEAR(open.true_range_m, 4.5, 1e-12);
  EXPECT_FALSE(wall.los);
  EXPECT_EQ(wall.obstruction.concrete, 1);
  EXPECT_GE(wall.excess_m, cp.concrete.delay_m);  // always longer
  EXPECT_LT(wall.rssi_mean_dbm, open.rssi_mean_dbm - 5.0);
  // Severity scales the excess, 0 removes it (the path stays NLOS).
  ChannelParams zero = cp, twice = cp;
  zero.nlos_severity = 0.0;
  twice.nlos_severity = 2.0;
  EXPECT_EQ(OfficeChannel(plan, anchors, Vec3::Zero(), zero, 42).link(1, standingAt(p_tag, 0.0)).excess_m, 0.0);
  EXPECT_FALSE(OfficeChannel(plan, anchors, Vec3::Zero(), zero, 42).link(1, standingAt(p_tag, 0.0)).los);
  EXPECT_NEAR(OfficeChannel(plan, anchors, Vec3::Zero(), twice, 42).link(1, standingAt(p_tag, 0.0)).excess_m,
              std::min(cp.nlos_max_excess_m, 2.0 * wall.excess_m), 1e-12);
  // Body shadowing: the same open anchor behind the wearer is NLOS.
  ChannelParams body = cp;
  body.body_shadowing = true;
  const OfficeChannel shadowed(plan, anchors, Vec3::Zero(), body, 42);
  EXPECT_TRUE(shadowed.link(0, standingAt(p_tag, M_PI)).los);    // facing the anchor (-x)
  const LinkState behind = shadowed.link(0, standingAt(p_tag, 0.0));  // anchor behind
  EXPECT_TRUE(behind.body_shadowed);
  EXPECT_FALSE(behind.los);
  EXPECT_GT(behind.excess_m, 0.0);
}

TEST(OfficeChannel, ExcessGrowsWithTheWallsCrossed) {
  OfficePlan plan = defaultOfficePlan();
  plan.obstacles.clear();
  ChannelParams cp;
  cp.body_shadowing = false;
  // Mean excess over many tag positions: one drywall (S1 -> corridor) vs two (S1 -> N1).
  const std::vector<Vec3> anchors{Vec3(3.0, 6.0, 2.5), Vec3(3.0, 9.5, 2.5)};
  const OfficeChannel channel(plan, anchors, Vec3::Zero(), cp, 7);
  double one = 0.0, two = 0.0;
  int n = 0;
  for (double x = 1.2; x <= 5.8; x += 0.2) {
    for (double y = 1.2; y <= 3.8; y += 0.2) {
      const KinematicState s = standingAt(Vec3(x, y, 1.3), 0.0);
      const LinkState a = channel.link(0, s), b = channel.link(1, s);
      if (a.obstruction.walls() != 1 || b.obstruction.walls() != 2) continue;
      one += a.excess_m;
      two += b.excess_m;
      ++n;
    }
  }
  ASSERT_GT(n, 100);
  EXPECT_GT(two / n, 1.3 * one / n);
}

// ---- Walk ------------------------------------------------------------------------

TEST(OfficeWalk, StaysInsideAndCrossesWallsOnlyThroughDoors) {
  for (int which = 0; which < 4; ++which) {
    const OfficePlan plan = which == 0 ? defaultOfficePlan() : randomOfficePlan(static_cast<std::uint64_t>(which));
    WalkParams wp;
    wp.seed = static_cast<std::uint64_t>(10 + which);
    wp.duration_s = 400.0;
    const OfficeWalk walk(plan, wp);
    Vec2 prev = walk.at(0.0).T_w_b.p.head<2>();
    int prev_space = plan.spaceAt(prev);
    int space_changes = 0;
    for (double t = 0.05; t <= wp.duration_s; t += 0.05) {
      const Vec3 p = walk.at(t).T_w_b.p;
      const Vec2 xy = p.head<2>();
      ASSERT_GE(plan.spaceAt(xy), 0) << "outside the building at t=" << t;
      ASSERT_GT(distanceToWalls(plan, xy), 0.2) << "too close to a wall at t=" << t << " p=" << xy.transpose();
      EXPECT_NEAR(p.z(), wp.body_height_m, 0.03);
      for (const Obstacle& o : plan.obstacles) {
        const Vec2 nearest = xy.cwiseMax(o.min_w).cwiseMin(o.max_w);
        ASSERT_GT((nearest - xy).norm(), 0.1) << "walked into furniture at t=" << t;
      }
      for (const Wall& w : plan.walls) ASSERT_FALSE(segmentsIntersect(prev, xy, w.a_w, w.b_w)) << "t=" << t;
      const int space = plan.spaceAt(xy);
      if (space != prev_space) {
        ++space_changes;
        bool through_door = false;
        for (const Door& d : plan.doors) {
          through_door = through_door || (((d.space_a == space && d.space_b == prev_space) ||
                                           (d.space_b == space && d.space_a == prev_space)) &&
                                          (xy - d.center_w).norm() < 0.5 * d.width_m + 0.3);
        }
        EXPECT_TRUE(through_door) << "changed space away from a door at t=" << t;
      }
      prev = xy;
      prev_space = space;
    }
    EXPECT_GT(space_changes, 4);  // it really walks through the office
  }
}

TEST(OfficeWalk, SpeedPausesAndStartWhileMoving) {
  WalkParams wp;
  wp.seed = 3;
  wp.duration_s = 300.0;
  const OfficeWalk walk(defaultOfficePlan(), wp);
  double v_max = 0.0, still = 0.0, fast = 0.0;
  for (double t = 0.0; t <= wp.duration_s; t += 0.02) {
    const double v = walk.at(t).v_w.head<2>().norm();
    v_max = std::max(v_max, v);
    still += v < 1e-6 ? 0.02 : 0.0;
    fast += v > wp.speed_min_m_s ? 0.02 : 0.0;
  }
  EXPECT_LE(v_max, wp.speed_max_m_s + 0.15);  // gait sway adds ~0.1 m/s sideways
  EXPECT_GT(still, 10.0);                      // pauses
  EXPECT_GT(fast, 100.0);                      // mostly walking at speed
  for (double t = 0.0; t < 1.6; t += 0.013) {  // standing still at the start: exactly
    const KinematicState st = walk.at(t);
    ASSERT_EQ(st.v_w, Vec3::Zero()) << t;
    ASSERT_EQ(st.a_w, Vec3::Zero()) << t;
    ASSERT_EQ(st.omega_b, Vec3::Zero()) << t;
    ASSERT_EQ(st.T_w_b.p, walk.at(0.0).T_w_b.p) << t;
  }
  EXPECT_EQ(walk.at(wp.duration_s + 1000.0).v_w.norm(), 0.0);

  wp.start_moving = true;
  const OfficeWalk moving(defaultOfficePlan(), wp);
  EXPECT_GT(moving.at(0.0).v_w.head<2>().norm(), 0.7);
}

TEST(OfficeWalk, DerivativesMatchFiniteDifferences) {
  WalkParams wp;
  wp.seed = 5;
  wp.duration_s = 120.0;
  const OfficeWalk walk(defaultOfficePlan(), wp);
  const double h = 1e-5;
  for (double t = 0.37; t < wp.duration_s; t += 0.731) {
    const KinematicState s = walk.at(t), sp = walk.at(t + h), sm = walk.at(t - h);
    const Vec3 v_fd = (sp.T_w_b.p - sm.T_w_b.p) / (2.0 * h);
    const Vec3 a_fd = (sp.v_w - sm.v_w) / (2.0 * h);
    EXPECT_LT((v_fd - s.v_w).norm(), 1e-6) << "t=" << t;
    EXPECT_LT((a_fd - s.a_w).norm(), 1e-4) << "t=" << t;
    // Body rates: R^T dR/dt = hat(omega_b).
    const Mat3 W = s.T_w_b.R.transpose() * (sp.T_w_b.R - sm.T_w_b.R) / (2.0 * h);
    const Vec3 omega_fd(W(2, 1), W(0, 2), W(1, 0));
    EXPECT_LT((omega_fd - s.omega_b).norm(), 1e-6) << "t=" << t;
  }
  // C2 across knots (every control_dt_s): acceleration continuous.
  for (double t = 1.0; t < wp.duration_s; t += 7.0 * wp.control_dt_s) {
    const double knot = std::round(t / wp.control_dt_s) * wp.control_dt_s;
    EXPECT_LT((walk.at(knot + 1e-9).a_w - walk.at(knot - 1e-9).a_w).norm(), 1e-5);
  }
}

// ---- Scenario: IMU and ranges ----------------------------------------------------

TEST(OfficeScenario, IntegratingTheIdealImuReproducesTheMotion) {
  OfficeScenarioParams p = shortParams(4, 20.0);
  p.gyro_noise_density = p.accel_noise_density = 0.0;
  p.gyro_bias_walk = p.accel_bias_walk = 0.0;
  p.gyro_bias_init_sigma = p.accel_bias_init_sigma = 0.0;
  p.walk.initial_still_s = 0.5;
  const Scenario s = simulateOfficeScenario(p);
  const KinematicState st0 = s.truthAt(s.imu.front().t_ns);
  Mat3 R = st0.T_w_b.R;
  Vec3 v = st0.v_w, x = st0.T_w_b.p;
  const Vec3 g(0.0, 0.0, -p.gravity_m_s2);
  for (std::size_t k = 0; k + 1 < s.imu.size(); ++k) {
    const double dt = 1e-9 * static_cast<double>(s.imu[k + 1].t_ns - s.imu[k].t_ns);
    // Trapezoid on the rotation and on the world acceleration.
    const Vec3 a0 = R * s.imu[k].accel_m_s2 + g;
    const Mat3 R1 = R * so3::exp(0.5 * (s.imu[k].gyro_rad_s + s.imu[k + 1].gyro_rad_s) * dt);
    const Vec3 a1 = R1 * s.imu[k + 1].accel_m_s2 + g;
    x += v * dt + (a0 / 3.0 + a1 / 6.0) * dt * dt;
    v += 0.5 * (a0 + a1) * dt;
    R = R1;
  }
  const KinematicState st1 = s.truthAt(s.imu.back().t_ns);
  // 20 s of a walk with bobbing and turns; the integration error alone is ~1e-4 m.
  EXPECT_LT((x - st1.T_w_b.p).norm(), 2e-3);
  EXPECT_LT((v - st1.v_w).norm(), 5e-4);
  EXPECT_LT(so3::log(R.transpose() * st1.T_w_b.R).norm(), 1e-5);
  EXPECT_GT((st1.T_w_b.p - st0.T_w_b.p).norm(), 1.0);  // it moved
}

TEST(OfficeScenario, ScenarioHasTheSharedShape) {
  const OfficeSimulation sim = simulateOffice(shortParams(1, 20.0));
  const Scenario& s = sim.scenario;
  EXPECT_EQ(s.p_w_anchors.size(), 8u);
  EXPECT_EQ(s.imu.size(), 16001u);
  EXPECT_EQ(s.imu_bias_truth.size(), s.imu.size());
  EXPECT_EQ(s.imu.front().t_ns, 1'000'000'000);
  EXPECT_EQ(s.imu[1].t_ns - s.imu[0].t_ns, 1'250'000);
  EXPECT_EQ(sim.range_truth.size(), s.ranges.size());
  EXPECT_EQ(sim.stats.ranges, s.ranges.size());
  EXPECT_DOUBLE_EQ(s.params.nlos_fraction, sim.stats.nlosFraction());
  EXPECT_EQ(s.biasAt(s.imu[5].t_ns), s.imu_bias_truth[5]);
  for (std::size_t i = 0; i < s.ranges.size(); ++i) {
    const RangeSample& r = s.ranges[i];
    if (i > 0) {
      EXPECT_GT(r.t_ns, s.ranges[i - 1].t_ns);
    }
    EXPECT_LT(r.anchor_id, 8u);
    EXPECT_TRUE(r.los == 0 || r.los == 1);
    EXPECT_TRUE(std::isfinite(r.rssi_dbm) && std::isfinite(r.fp_power_dbm));
    EXPECT_LE(r.fp_power_dbm, r.rssi_dbm);
    EXPECT_GE(r.range_m, 0.0);
    // The truth matches the geometry at the range time.
    const KinematicState st = s.truthAt(r.t_ns);
    EXPECT_NEAR((st.T_w_b.transformFrom(s.p_b_tag) - s.p_w_anchors[r.anchor_id]).norm(), sim.range_truth[i].true_range_m,
                1e-9);
    EXPECT_EQ(r.los == 1, sim.setup.channel->link(r.anchor_id, st).los);
  }
}

TEST(OfficeScenario, LosRangesAreUnbiasedAndNlosRangesLonger) {
  const OfficeSimulation sim = simulateOffice(shortParams(2, 300.0));
  double los_sum = 0.0, los_sq = 0.0, nlos_sum = 0.0;
  int n_los = 0, n_nlos = 0;
  for (std::size_t i = 0; i < sim.scenario.ranges.size(); ++i) {
    const RangeTruth& t = sim.range_truth[i];
    if (t.outlier) continue;
    if (sim.scenario.ranges[i].los == 1) {
      los_sum += t.error_m;
      los_sq += t.error_m * t.error_m;
      ++n_los;
    } else {
      nlos_sum += t.error_m;
      ++n_nlos;
    }
  }
  ASSERT_GT(n_los, 500);
  ASSERT_GT(n_nlos, 500);
  const double los_mean = los_sum / n_los;
  EXPECT_LT(std::abs(los_mean), 0.05);  // calibration residuals of a few cm only
  EXPECT_NEAR(std::sqrt(los_sq / n_los - los_mean * los_mean), 0.10, 0.03);
  EXPECT_GT(nlos_sum / n_nlos, los_mean + 0.15);
}

TEST(OfficeScenario, NlosPersistsForSeconds) {
  const OfficeSimulation sim = simulateOffice(shortParams(3, 300.0));
  const std::vector<RangeSample>& r = sim.scenario.ranges;
  // Per anchor: consecutive ranges (< 1 s apart) with the same LOS state form an episode.
  std::map<std::uint32_t, std::pair<std::int64_t, std::int64_t>> open;  // anchor -> (start, last) of an NLOS run
  std::map<std::uint32_t, std::size_t> last_index;
  double total_s = 0.0;
  int episodes = 0;
  auto close = [&](std::uint32_t a) {
    total_s += 1e-9 * static_cast<double>(open[a].second - open[a].first);
    ++episodes;
    open.erase(a);
  };
  int correlated_pairs = 0, pairs = 0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const std::uint32_t a = r[i].anchor_id;
    const bool continues = last_index.count(a) && r[i].t_ns - r[last_index[a]].t_ns < 1'000'000'000;
    if (open.count(a) && (!continues || r[i].los == 1)) close(a);
    if (r[i].los == 0) {
      if (!open.count(a)) open[a] = {r[i].t_ns, r[i].t_ns};
      open[a].second = r[i].t_ns;
      // The excess changes little between ranges 0.1 s apart: it follows the geometry.
      if (continues && r[last_index[a]].los == 0 && r[i].t_ns - r[last_index[a]].t_ns < 200'000'000 &&
          sim.range_truth[i].obstruction.walls() == sim.range_truth[last_index[a]].obstruction.walls()) {
        ++pairs;
        const double e0 = sim.range_truth[last_index[a]].excess_m, e1 = sim.range_truth[i].excess_m;
        correlated_pairs += std::abs(e1 - e0) < 0.1 + 0.2 * std::max(e0, e1) ? 1 : 0;
      }
    }
    last_index[a] = i;
  }
  while (!open.empty()) close(open.begin()->first);
  ASSERT_GT(episodes, 10);
  EXPECT_GT(total_s / episodes, 2.0) << episodes << " NLOS episodes";
  ASSERT_GT(pairs, 100);
  EXPECT_GT(static_cast<double>(correlated_pairs) / pairs, 0.9);
}

TEST(OfficeScenario, RangesTheStrongestAnchorsOfEachCycle) {
  OfficeScenarioParams p = shortParams(6, 60.0);
  p.selection_fading_db = 0.0;
  p.packet_loss = 0.0;
  const OfficeSimulation sim = simulateOffice(p);
  const double cycle_s = p.ranges_per_cycle / p.range_rate_hz;
  std::map<std::size_t, std::vector<std::uint32_t>> by_cycle;
  for (std::size_t i = 0; i < sim.scenario.ranges.size(); ++i) {
    by_cycle[sim.range_truth[i].cycle].push_back(sim.scenario.ranges[i].anchor_id);
  }
  ASSERT_GT(by_cycle.size(), 100u);
  for (const auto& [cycle, anchors] : by_cycle) {
    const KinematicState st = sim.setup.walk->at(static_cast<double>(cycle) * cycle_s);
    const std::vector<std::size_t> ranked = rankAnchors(*sim.setup.channel, st, {});
    ASSERT_EQ(anchors.size(), std::min<std::size_t>(ranked.size(), 4)) << "cycle " << cycle;
    for (std::size_t k = 0; k < anchors.size(); ++k) EXPECT_EQ(anchors[k], ranked[k]) << "cycle " << cycle;
    for (std::size_t k = 1; k < ranked.size(); ++k) {
      EXPECT_GE(sim.setup.channel->link(ranked[k - 1], st).rssi_mean_dbm, sim.setup.channel->link(ranked[k], st).rssi_mean_dbm);
    }
  }
  // With 40 Hz in cycles of 4 and no loss: 40 ranges/s unless an anchor is not heard.
  EXPECT_NEAR(sim.stats.rangesPerSecond(), 40.0 * (1.0 - static_cast<double>(sim.stats.empty_slots) /
                                                             static_cast<double>(4 * sim.stats.cycles)), 0.2);
}

TEST(OfficeScenario, DeterministicPerSeed) {
  OfficeScenarioParams p = shortParams(5, 15.0);
  p.plan = OfficePlanKind::kRandom;
  const Scenario a = simulateOfficeScenario(p), b = simulateOfficeScenario(p);
  ASSERT_EQ(a.imu.size(), b.imu.size());
  for (std::size_t i = 0; i < a.imu.size(); ++i) {
    ASSERT_EQ(a.imu[i].gyro_rad_s, b.imu[i].gyro_rad_s);
    ASSERT_EQ(a.imu[i].accel_m_s2, b.imu[i].accel_m_s2);
  }
  ASSERT_EQ(a.ranges.size(), b.ranges.size());
  for (std::size_t i = 0; i < a.ranges.size(); ++i) {
    ASSERT_EQ(a.ranges[i].t_ns, b.ranges[i].t_ns);
    ASSERT_EQ(a.ranges[i].anchor_id, b.ranges[i].anchor_id);
    ASSERT_EQ(a.ranges[i].range_m, b.ranges[i].range_m);
    ASSERT_EQ(a.ranges[i].rssi_dbm, b.ranges[i].rssi_dbm);
  }
  p.seed = 6;
  const Scenario c = simulateOfficeScenario(p);
  EXPECT_NE(c.p_w_anchors, a.p_w_anchors);  // another random plan
  EXPECT_NE(c.imu[100].accel_m_s2, a.imu[100].accel_m_s2);
}

// A receiver without the first-path power: the same session, the same
// ranges and RX levels, the indicator's column empty.
TEST(OfficeScenario, ReceiverWithoutFirstPathPowerReportsTheRxLevelOnly) {
  OfficeScenarioParams p = shortParams(2, 10.0);
  const Scenario with = simulateOfficeScenario(p);
  p.report_first_path = false;
  const Scenario without = simulateOfficeScenario(p);
  ASSERT_EQ(with.ranges.size(), without.ranges.size());
  ASSERT_GT(without.ranges.size(), 100u);
  for (std::size_t i = 0; i < with.ranges.size(); ++i) {
    ASSERT_EQ(with.ranges[i].range_m, without.ranges[i].range_m);
    ASSERT_EQ(with.ranges[i].rssi_dbm, without.ranges[i].rssi_dbm);
    ASSERT_TRUE(std::isfinite(with.ranges[i].fp_power_dbm));
    ASSERT_TRUE(std::isnan(without.ranges[i].fp_power_dbm));
  }
}

TEST(OfficeScenario, PacketLossAndOutliersAtTheirRates) {
  OfficeScenarioParams p = shortParams(7, 300.0);
  p.packet_loss = 0.2;
  p.outlier_probability = 0.02;
  const OfficeStats st = simulateOffice(p).stats;
  EXPECT_NEAR(static_cast<double>(st.lost) / static_cast<double>(st.slots), 0.2, 0.02);
  EXPECT_NEAR(st.outlierRate(), 0.02, 0.006);
  EXPECT_EQ(st.ranges + st.lost, st.slots);
}

TEST(OfficeScenario, InvalidParamsThrow) {
  OfficeScenarioParams p;
  p.ranges_per_cycle = 0;
  EXPECT_THROW(simulateOffice(p), std::invalid_argument);
  p = OfficeScenarioParams{};
  p.packet_loss = 1.0;
  EXPECT_THROW(simulateOffice(p), std::invalid_argument);
  p = OfficeScenarioParams{};
  p.channel.nlos_severity = -1.0;
  EXPECT_THROW(simulateOffice(p), std::invalid_argument);
  p = OfficeScenarioParams{};
  p.walk.speed_min_m_s = 2.0;  // above speed_max
  EXPECT_THROW(simulateOffice(p), std::invalid_argument);
}

}  // namespace
}  // namespace rilo::sim
