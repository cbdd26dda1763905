// TDoA initialization (IMU-Ultrasonic-UWB paper, Sec. III-B): the spherical-intersection
// closed form, the robust fix from a window of mixed-reference TDoA rows
// (noise-free, Gaussian noise, 30 % NLOS rows, a blocked anchor), the
// ultrasonic-enhanced fix, degenerate geometry and malformed input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "estimation/init/tdoa.h"
#include "estimation/noise/gaussian_loss.h"
#include "estimation/noise/huber_loss.h"
#include "sim/office_scenario.h"
#include "sim/office_tdoa.h"
#include "sim/office_ultrasonic.h"
#include "sim/range_imu_scenario.h"
#include "support/expect_throws_naming.h"

namespace rilo {
namespace {

using rilo::testing::expectThrowsNaming;

// ---------------------------------------------------------------------------
// Scenarios

struct RowOptions {
  double sigma_m = 0.0;
  int rounds = 10;
  double packet_loss = 0.1;   ///< a lost packet makes the next row refer to an older anchor
  double nlos_fraction = 0.0; ///< rows with an NLOS excess on one of their two paths
  std::vector<int> blocked;   ///< these anchors' paths are always longer by blocked_excess_m
  double blocked_excess_m = 1.0;
  bool random_pairs = false;  ///< any reference, not the previous packet's anchor
  Vec3 v_w = Vec3::Zero();    ///< tag velocity over the window (m/s)
  double round_s = 0.05;
};

double pathExcess(int anchor, const RowOptions& o) {
  return std::find(o.blocked.begin(), o.blocked.end(), anchor) != o.blocked.end() ? o.blocked_excess_m : 0.0;
}

/// TDoA3-like rows: anchors transmit in turn, each received packet of b is
/// paired with the previously received packet of another anchor a.
std::vector<TdoaSample> tdoaRows(const std::vector<Vec3>& anchors, const Vec3& p0, std::uint64_t seed,
                                 const RowOptions& o) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::exponential_distribution<double> excess(1.0 / 0.7);
  const int n = static_cast<int>(anchors.size());
  std::vector<TdoaSample> out;
  int previous = -1;
  for (int round = 0; round < o.rounds; ++round) {
    for (int b = 0; b < n; ++b) {
      const double t_s = o.round_s * (round + static_cast<double>(b) / n);
      if (u01(rng) < o.packet_loss) continue;
      int a = previous;
      if (o.random_pairs) {
        a = static_cast<int>(u01(rng) * n) % n;
        if (a == b) a = (a + 1) % n;
      }
      previous = b;
      if (a < 0 || a == b) continue;
      const Vec3 p = p0 + o.v_w * t_s;
      TdoaSample s;
      s.t_ns = 1'000'000'000 + std::llround(t_s * 1e9);
      s.anchor_a = static_cast<std::uint32_t>(a);
      s.anchor_b = static_cast<std::uint32_t>(b);
      s.diff_m = (p - anchors[static_cast<std::size_t>(b)]).norm() - (p - anchors[static_cast<std::size_t>(a)]).norm();
      s.diff_m += pathExcess(b, o) - pathExcess(a, o);
      if (u01(rng) < o.nlos_fraction) {
        // NLOS on one path: b late makes the difference longer, a late shorter.
        const double e = 0.3 + excess(rng);
        s.diff_m += u01(rng) < 0.5 ? e : -e;
        s.los = 0;
      }
      s.diff_m += o.sigma_m * n01(rng);
      out.push_back(s);
    }
  }
  return out;
}

std::vector<UltrasonicSample> ultrasonicRanges(const std::vector<Vec3>& anchors, const std::vector<std::uint32_t>& ids,
                                               const Vec3& p, int rounds, double sigma_m, std::uint64_t seed,
                                               int reflected_id = -1, double reflection_m = 0.0) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<UltrasonicSample> out;
  for (int r = 0; r < rounds; ++r) {
    for (std::uint32_t id : ids) {
      UltrasonicSample u;
      u.t_ns = 1'000'000'000 + r * 100'000'000LL;
      u.anchor_id = id;
      u.range_m = (p - anchors[id]).norm() + sigma_m * n01(rng);
      if (static_cast<int>(id) == reflected_id) u.range_m += reflection_m;
      out.push_back(u);
    }
  }
  return out;
}

TdoaFixParams fixParams(double sigma_m = 0.1) {
  TdoaFixParams p;
  p.sigma_m = sigma_m;
  return p;
}

/// Plain least squares: Gaussian loss, no consensus.
TdoaFixParams plainParams(double sigma_m = 0.1) {
  TdoaFixParams p = fixParams(sigma_m);
  p.loss = std::make_shared<GaussianLoss>();
  p.consensus = false;
  return p;
}

/// Tag positions inside the default office (anchors at 0.6-2.8 m on the walls of 14 x 11 m).
std::vector<Vec3> officePositions() {
  return {{1.0, -2.0, 1.3}, {-4.0, 3.0, 1.1}, {5.0, 4.0, 1.7}, {0.0, 0.0, 1.5}, {-5.5, -4.0, 0.95}, {3.3, -4.2, 1.8}};
}

// ---------------------------------------------------------------------------
// Closed form

int closestCandidate(const TdoaClosedForm& cf, const Vec3& p, double* err) {
  int best = -1;
  *err = std::numeric_limits<double>::infinity();
  for (int i = 0; i < cf.count; ++i) {
    const double e = (cf.p_w[static_cast<std::size_t>(i)] - p).norm();
    if (e < *err) {
      *err = e;
      best = i;
    }
  }
  return best;
}

TEST(TdoaClosedForm, NoiseFreeRecoversThePositionFromFourToEightAnchors) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> ux(-6.0, 6.0), uy(-4.5, 4.5), uz(0.2, 2.8);
  for (int trial = 0; trial < 50; ++trial) {
    const Vec3 p(ux(rng), uy(rng), uz(rng));
    for (std::size_t n : {4u, 5u, 8u}) {
      std::vector<Vec3> others;
      std::vector<double> d;
      for (std::size_t i = 1; i < n; ++i) {
        others.push_back(anchors[i]);
        d.push_back((p - anchors[i]).norm() - (p - anchors[0]).norm());
      }
      const TdoaClosedForm cf = tdoaSphericalIntersection(anchors[0], others, d);
      ASSERT_GT(cf.count, 0) << cf.failure;
      EXPECT_FALSE(cf.planar);
      double err = 0.0;
      closestCandidate(cf, p, &err);
      EXPECT_LT(err, 1e-6) << "trial " << trial << ", " << n << " anchors";
    }
  }
}

TEST(TdoaClosedForm, CoplanarAnchorsGiveTheMirrorPair) {
  const std::vector<Vec3> ceiling = {{-5, -4, 2.8}, {5, -4, 2.8}, {5, 4, 2.8}, {-5, 4, 2.8}, {0, 0, 2.8}};
  const Vec3 p(1.2, -0.7, 1.3);
  std::vector<Vec3> others(ceiling.begin() + 1, ceiling.end());
  std::vector<double> d;
  for (const Vec3& a : others) d.push_back((p - a).norm() - (p - ceiling[0]).norm());
  const TdoaClosedForm cf = tdoaSphericalIntersection(ceiling[0], others, d);
  ASSERT_EQ(cf.count, 2) << cf.failure;
  EXPECT_TRUE(cf.planar);
  double err = 0.0;
  const int k = closestCandidate(cf, p, &err);
  EXPECT_LT(err, 1e-6);
  const Vec3 mirror = cf.p_w[static_cast<std::size_t>(1 - k)];
  EXPECT_NEAR(mirror.z(), 2.8 + (2.8 - p.z()), 1e-6);  // reflected across the ceiling
  EXPECT_LT((mirror.head<2>() - p.head<2>()).norm(), 1e-6);
}

TEST(TdoaClosedForm, CollinearAnchorsAndBadArgumentsAreReported) {
  const std::vector<Vec3> line = {{1, 0, 2}, {2, 0, 2}, {3, 0, 2}};
  const std::vector<double> d = {0.5, 1.0, 1.5};
  const TdoaClosedForm cf = tdoaSphericalIntersection(Vec3(0, 0, 2), line, d);
  EXPECT_EQ(cf.count, 0);
  EXPECT_NE(cf.failure.find("collinear"), std::string::npos) << cf.failure;
  const TdoaClosedForm two = tdoaSphericalIntersection(Vec3::Zero(), std::span<const Vec3>(line).first(2),
                                                       std::span<const double>(d).first(2));
  EXPECT_EQ(two.count, 0);
  EXPECT_NE(two.failure.find("need 3"), std::string::npos) << two.failure;
  EXPECT_THROW(tdoaSphericalIntersection(Vec3::Zero(), line, std::span<const double>(d).first(2)),
               std::invalid_argument);
}

// ---------------------------------------------------------------------------
// The fix

TEST(TdoaFix, NoiseFreeRowsRecoverThePosition) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  std::uint64_t seed = 10;
  for (const Vec3& p : officePositions()) {
    for (bool random_pairs : {false, true}) {
      RowOptions o;
      o.random_pairs = random_pairs;
      const std::vector<TdoaSample> rows = tdoaRows(anchors, p, ++seed, o);
      const TdoaFix fix = locateTdoa(rows, {}, 0, anchors, fixParams());
      ASSERT_TRUE(fix.valid) << fix.message;
      EXPECT_EQ(fix.failure, TdoaFixFailure::kNone);
      EXPECT_LT((fix.p_w_tag - p).norm(), 1e-6) << fix.message;
      EXPECT_EQ(fix.anchors_heard, 8);
      EXPECT_EQ(fix.anchors_used, 8);
      EXPECT_EQ(fix.inliers, fix.measurements);
      EXPECT_LT(fix.rms_m, 1e-6);
      EXPECT_LT(fix.pdop, 5.0);
      EXPECT_GT(fix.hypotheses, 70);  // all 70 four-anchor subsets and the all-anchor solution
    }
  }
}

TEST(TdoaFix, GaussianNoiseErrorWithinAFewSigma) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  double sum_err2 = 0.0, sum_trace = 0.0, max_err = 0.0;
  int count = 0;
  std::uint64_t seed = 100;
  for (const Vec3& p : officePositions()) {
    for (int rep = 0; rep < 8; ++rep) {
      RowOptions o;
      o.sigma_m = 0.1;
      const std::vector<TdoaSample> rows = tdoaRows(anchors, p, ++seed, o);
      const TdoaFix fix = locateTdoa(rows, {}, 0, anchors, fixParams(0.1));
      ASSERT_TRUE(fix.valid) << fix.message;
      const double err = (fix.p_w_tag - p).norm();
      EXPECT_LT(err, 4.0 * fix.sigma_p_m) << fix.message;
      EXPECT_LT(err, 0.3) << fix.message;
      EXPECT_NEAR(fix.rms_m, 0.1, 0.03) << fix.message;
      EXPECT_GE(fix.inliers, fix.measurements * 95 / 100);
      sum_err2 += err * err;
      sum_trace += fix.cov_p.trace();
      max_err = std::max(max_err, err);
      ++count;
    }
  }
  const double rmse = std::sqrt(sum_err2 / count), predicted = std::sqrt(sum_trace / count);
  std::printf("[ info ] sigma 0.1 m, 8 anchors, ~70 rows: RMSE %.3f m (predicted %.3f m), max %.3f m over %d fixes\n",
              rmse, predicted, max_err, count);
  EXPECT_LT(rmse, 0.1);
  EXPECT_GT(rmse / predicted, 0.5);  // the covariance is honest within a factor 2
  EXPECT_LT(rmse / predicted, 2.0);
}

TEST(TdoaFix, ThirtyPercentNlosRowsRobustBeatsPlainLeastSquares) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  double robust_sum = 0.0, plain_sum = 0.0, huber_sum = 0.0;
  int count = 0, valid = 0;
  std::uint64_t seed = 200;
  for (const Vec3& p : officePositions()) {
    for (int rep = 0; rep < 5; ++rep) {
      RowOptions o;
      o.sigma_m = 0.1;
      o.nlos_fraction = 0.3;
      o.rounds = 20;
      const std::vector<TdoaSample> rows = tdoaRows(anchors, p, ++seed, o);
      const TdoaFix robust = locateTdoa(rows, {}, 0, anchors, fixParams(0.1));
      const TdoaFix plain = locateTdoa(rows, {}, 0, anchors, plainParams(0.1));
      TdoaFixParams hp = fixParams(0.1);
      hp.loss = std::make_shared<HuberLoss>();
      const TdoaFix huber = locateTdoa(rows, {}, 0, anchors, hp);
      robust_sum += (robust.p_w_tag - p).norm();
      plain_sum += (plain.p_w_tag - p).norm();
      huber_sum += (huber.p_w_tag - p).norm();
      valid += robust.valid ? 1 : 0;
      ++count;
    }
  }
  const double robust_mean = robust_sum / count, plain_mean = plain_sum / count, huber_mean = huber_sum / count;
  std::printf("[ info ] 30%% NLOS rows: mean error robust %.3f m, Huber %.3f m, plain LS %.3f m (%d fixes)\n",
              robust_mean, huber_mean, plain_mean, count);
  EXPECT_LT(robust_mean, 0.12);
  EXPECT_LT(robust_mean, 0.4 * plain_mean);
  EXPECT_LT(huber_mean, plain_mean);
  EXPECT_EQ(valid, count);
}

TEST(TdoaFix, BlockedAnchorsAreRejected) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  std::uint64_t seed = 300;
  for (const std::vector<int>& blocked : std::vector<std::vector<int>>{{0}, {3}, {5}, {1, 6}, {2, 7}}) {
    const Vec3 p(1.0, -2.0, 1.3);
    RowOptions o;
    o.sigma_m = 0.05;
    o.blocked = blocked;
    o.blocked_excess_m = 1.0;
    const std::vector<TdoaSample> rows = tdoaRows(anchors, p, ++seed, o);
    const TdoaFix fix = locateTdoa(rows, {}, 0, anchors, fixParams(0.05));
    const TdoaFix plain = locateTdoa(rows, {}, 0, anchors, plainParams(0.05));
    ASSERT_TRUE(fix.valid) << fix.message;
    // Without two of the three low anchors (1, 6) the height is weak: within 3 sigma.
    EXPECT_LT((fix.p_w_tag - p).norm(), std::max(0.1, 3.0 * fix.sigma_p_m)) << fix.message;
    EXPECT_EQ(fix.anchors_rejected, static_cast<int>(blocked.size())) << fix.message;
    EXPECT_EQ(fix.anchors_used, 8 - static_cast<int>(blocked.size())) << fix.message;  // no inlier row touches them
    EXPECT_GT((plain.p_w_tag - p).norm(), 0.3) << plain.message;
  }
}

TEST(TdoaFix, DisjointPairsStillConstrainThePosition) {
  // Rows only within the pairs (0, 1), (2, 3), (4, 5), (6, 7): no common
  // reference for the closed form, but four independent differences.
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  const Vec3 p(1.0, -2.0, 1.3);
  std::vector<TdoaSample> rows;
  for (int k = 0; k < 40; ++k) {
    TdoaSample s;
    s.anchor_a = static_cast<std::uint32_t>(2 * (k % 4));
    s.anchor_b = s.anchor_a + 1;
    s.diff_m = (p - anchors[s.anchor_b]).norm() - (p - anchors[s.anchor_a]).norm();
    rows.push_back(s);
  }
  const TdoaFix fix = locateTdoa(rows, {}, 0, anchors, fixParams());
  EXPECT_EQ(fix.anchors_heard, 8);
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_LT((fix.p_w_tag - p).norm(), 1e-6) << fix.message;
}

TEST(TdoaFix, SlowlyMovingTagIsFixedNearTheWindowMiddle) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  RowOptions o;
  o.sigma_m = 0.05;
  o.v_w = Vec3(0.3, 0.2, 0.0);  // slow walk over a 0.5 s window
  const Vec3 p0(0.0, 1.0, 1.4);
  const std::vector<TdoaSample> rows = tdoaRows(anchors, p0, 400, o);
  const TdoaFix fix = locateTdoa(rows, {}, rows[rows.size() / 2].t_ns, anchors, fixParams(0.05));
  ASSERT_TRUE(fix.valid) << fix.message;
  const Vec3 p_mid = p0 + o.v_w * (0.5 * o.rounds * o.round_s);
  EXPECT_LT((fix.p_w_tag - p_mid).norm(), 0.15) << fix.message;
}

// ---------------------------------------------------------------------------
// Ultrasonic

/// The default office plus 4 ultrasonic beacons on the ceiling (ids 8-11).
std::vector<Vec3> officeWithBeacons() {
  std::vector<Vec3> a = sim::defaultOfficeAnchors();
  for (const Vec3& b : {Vec3(-3, -2, 2.95), Vec3(3, -2, 2.95), Vec3(3, 2.5, 2.95), Vec3(-3, 2.5, 2.95)}) a.push_back(b);
  return a;
}
const std::vector<std::uint32_t> kBeacons = {8, 9, 10, 11};

TEST(TdoaFixUltrasonic, UltrasonicRangesImproveTheError) {
  const std::vector<Vec3> anchors = officeWithBeacons();
  double with_sum = 0.0, without_sum = 0.0;
  int count = 0;
  std::uint64_t seed = 500;
  TdoaFixParams params = fixParams(0.15);
  params.ultrasonic_sigma_m = 0.02;
  for (const Vec3& p : officePositions()) {
    for (int rep = 0; rep < 5; ++rep) {
      RowOptions o;
      o.sigma_m = 0.15;
      o.nlos_fraction = 0.1;
      const std::vector<TdoaSample> rows = tdoaRows(anchors, p, ++seed, o);
      const std::vector<UltrasonicSample> us = ultrasonicRanges(anchors, kBeacons, p, 5, 0.02, ++seed);
      const TdoaFix with = locateTdoa(rows, us, 0, anchors, params);
      const TdoaFix without = locateTdoa(rows, {}, 0, anchors, params);
      ASSERT_TRUE(with.valid) << with.message << "\nTDoA only: " << without.message;
      EXPECT_EQ(with.beacons_heard, 4);
      EXPECT_GE(with.ultrasonic_inliers, with.ultrasonic_ranges - 2);  // 3-sigma gate on Gaussian ranges
      EXPECT_LT(with.sigma_p_m, without.sigma_p_m);
      with_sum += (with.p_w_tag - p).norm();
      without_sum += (without.p_w_tag - p).norm();
      ++count;
    }
  }
  std::printf("[ info ] TDoA sigma 0.15 m + 4 ultrasonic beacons at 0.02 m: mean error %.3f m (TDoA only %.3f m)\n",
              with_sum / count, without_sum / count);
  EXPECT_LT(with_sum / count, 0.5 * without_sum / count);
  EXPECT_LT(with_sum / count, 0.05);
}

TEST(TdoaFixUltrasonic, ReflectedBeaconIsRejected) {
  const std::vector<Vec3> anchors = officeWithBeacons();
  const Vec3 p(-1.0, 0.5, 1.2);
  RowOptions o;
  o.sigma_m = 0.15;
  const std::vector<TdoaSample> rows = tdoaRows(anchors, p, 600, o);
  const std::vector<UltrasonicSample> us = ultrasonicRanges(anchors, kBeacons, p, 5, 0.02, 601, 9, 0.6);
  TdoaFixParams params = fixParams(0.15);
  params.ultrasonic_sigma_m = 0.02;
  const TdoaFix fix = locateTdoa(rows, us, 0, anchors, params);
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_EQ(fix.ultrasonic_inliers, 15);  // the reflected beacon's 5 ranges are out
  EXPECT_LT((fix.p_w_tag - p).norm(), 0.06) << fix.message;
}

TEST(TdoaFixUltrasonic, UltrasonicPicksTheRootWhenTheTdoaGeometryIsAmbiguous) {
  // Five anchors on one wall: TDoA alone fits the mirror behind the wall as
  // well as the true position, and the height band cannot tell them apart.
  std::vector<Vec3> anchors = {{-6, -4, 0.5}, {-6, 4, 0.5}, {-6, -4, 2.7}, {-6, 4, 2.7}, {-6, 0, 1.6}};
  anchors.push_back({1.0, 0.0, 2.95});  // ultrasonic beacon on the ceiling, id 5
  const Vec3 p(-2.0, 1.0, 1.3);
  RowOptions o;
  o.sigma_m = 0.05;
  const std::vector<Vec3> uwb(anchors.begin(), anchors.begin() + 5);
  const std::vector<TdoaSample> rows = tdoaRows(uwb, p, 700, o);
  TdoaFixParams params = fixParams(0.05);
  params.ultrasonic_sigma_m = 0.02;
  const TdoaFix tdoa_only = locateTdoa(rows, {}, 0, anchors, params);
  EXPECT_FALSE(tdoa_only.valid);
  EXPECT_EQ(tdoa_only.failure, TdoaFixFailure::kAmbiguous) << tdoa_only.message;

  const std::vector<UltrasonicSample> us = ultrasonicRanges(anchors, {5}, p, 5, 0.02, 701);
  const TdoaFix fix = locateTdoa(rows, us, 0, anchors, params);
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_LT((fix.p_w_tag - p).norm(), 0.15) << fix.message;
  std::printf("[ info ] wall anchors: TDoA only: %s\n[ info ] with one beacon: %s\n", tdoa_only.message.c_str(),
              fix.message.c_str());
}

TEST(TdoaFixUltrasonic, ThreeAnchorsAndTwoBeaconsAreEnough) {
  const std::vector<Vec3> all = officeWithBeacons();
  std::vector<Vec3> anchors = {all[0], all[2], all[5]};
  anchors.push_back(all[8]);  // beacon id 3
  anchors.push_back(all[10]); // beacon id 4
  const Vec3 p(0.5, -0.5, 1.3);
  RowOptions o;
  o.sigma_m = 0.05;
  const std::vector<TdoaSample> rows = tdoaRows({anchors[0], anchors[1], anchors[2]}, p, 800, o);
  TdoaFixParams params = fixParams(0.05);
  params.ultrasonic_sigma_m = 0.02;
  const TdoaFix no_us = locateTdoa(rows, {}, 0, anchors, params);
  EXPECT_FALSE(no_us.valid);
  EXPECT_EQ(no_us.failure, TdoaFixFailure::kTooFewAnchors);
  const std::vector<UltrasonicSample> us = ultrasonicRanges(anchors, {3, 4}, p, 5, 0.02, 801);
  const TdoaFix fix = locateTdoa(rows, us, 0, anchors, params);
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_LT((fix.p_w_tag - p).norm(), 0.1) << fix.message;
}

// ---------------------------------------------------------------------------
// Office simulator (walls, furniture, people, the wearer's body; walking)

struct OfficeWindows {
  std::vector<double> errors_tdoa, errors_us;      ///< of the valid fixes (m)
  std::vector<double> horizontal_tdoa, horizontal_us;  ///< their horizontal part (m)
  int windows = 0, valid_tdoa = 0, valid_us = 0;
};

/// Fixes from 0.25 s windows every 2 s of a simulated office walk, TDoA only
/// and TDoA + ultrasonic, against the UWB antenna at the window's middle.
OfficeWindows officeWindows(std::uint64_t seed, std::int64_t window_ns) {
  sim::OfficeScenarioParams op;
  op.seed = seed;
  op.duration_s = 60.0;
  op.tdoa.enabled = true;
  op.ultrasonic.enabled = true;
  const sim::OfficeSetup setup = sim::makeOfficeSetup(op);
  std::vector<TdoaSample> rows;
  std::vector<UltrasonicSample> us;
  {
    sim::OfficeTdoaStream stream(op, setup);
    TdoaSample s;
    sim::TdoaTruth t;
    while (stream.next(s, t)) rows.push_back(s);
    sim::OfficeUltrasonicStream ustream(op, setup);
    UltrasonicSample u;
    sim::UltrasonicTruth ut;
    while (ustream.next(u, ut)) us.push_back(u);
  }
  std::vector<Vec3> anchors = setup.p_w_anchors;
  for (const Vec3& b : setup.p_w_ultrasonic) anchors.push_back(b);

  TdoaFixParams params;
  params.sigma_m = op.tdoa.sigma_m;
  params.ultrasonic_sigma_m = op.ultrasonic.sigma_m;
  params.ultrasonic_offset_m = (op.ultrasonic.p_b_receiver - op.p_b_tag).norm();
  OfficeWindows out;
  for (std::int64_t t0 = op.t0_ns + 1'000'000'000; t0 + window_ns < op.t0_ns + 59'000'000'000;
       t0 += 2'000'000'000) {
    auto in = [&](const auto& x) { return x.t_ns >= t0 && x.t_ns < t0 + window_ns; };
    std::vector<TdoaSample> w;
    std::copy_if(rows.begin(), rows.end(), std::back_inserter(w), in);
    std::vector<UltrasonicSample> wu;
    std::copy_if(us.begin(), us.end(), std::back_inserter(wu), in);
    const std::int64_t t_mid = t0 + window_ns / 2;
    const Vec3 truth = setup.walk->at(1e-9 * static_cast<double>(t_mid - op.t0_ns)).T_w_b.transformFrom(op.p_b_tag);
    const TdoaFix a = locateTdoa(w, {}, t_mid, anchors, params);
    const TdoaFix b = locateTdoa(w, wu, t_mid, anchors, params);
    ++out.windows;
    if (a.valid) {
      ++out.valid_tdoa;
      out.errors_tdoa.push_back((a.p_w_tag - truth).norm());
      out.horizontal_tdoa.push_back((a.p_w_tag - truth).head<2>().norm());
    }
    if (b.valid) {
      ++out.valid_us;
      out.errors_us.push_back((b.p_w_tag - truth).norm());
      out.horizontal_us.push_back((b.p_w_tag - truth).head<2>().norm());
    }
  }
  return out;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::infinity();
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

TEST(TdoaFixOffice, WalkingInTheSimulatedOffice) {
  for (std::int64_t window_ns : {250'000'000LL, 500'000'000LL}) {
    OfficeWindows all;
    for (std::uint64_t seed : {1u, 2u, 3u}) {
      const OfficeWindows w = officeWindows(seed, window_ns);
      all.windows += w.windows;
      all.valid_tdoa += w.valid_tdoa;
      all.valid_us += w.valid_us;
      auto append = [](std::vector<double>& to, const std::vector<double>& from) {
        to.insert(to.end(), from.begin(), from.end());
      };
      append(all.errors_tdoa, w.errors_tdoa);
      append(all.errors_us, w.errors_us);
      append(all.horizontal_tdoa, w.horizontal_tdoa);
      append(all.horizontal_us, w.horizontal_us);
    }
    std::printf("[ info ] office, %.2f s windows while walking: TDoA %d/%d valid, error median %.2f m (horizontal "
                "%.2f m), p90 %.2f m (%.2f m)\n",
                1e-9 * static_cast<double>(window_ns), all.valid_tdoa, all.windows, quantile(all.errors_tdoa, 0.5),
                quantile(all.horizontal_tdoa, 0.5), quantile(all.errors_tdoa, 0.9), quantile(all.horizontal_tdoa, 0.9));
    std::printf("[ info ]   + ultrasonic: %d/%d valid, error median %.2f m (horizontal %.2f m), p90 %.2f m (%.2f m)\n",
                all.valid_us, all.windows, quantile(all.errors_us, 0.5), quantile(all.horizontal_us, 0.5),
                quantile(all.errors_us, 0.9), quantile(all.horizontal_us, 0.9));
    // A harsh place for TDoA (both paths of a row must be clear; most rows
    // have a blocked one): the fix is refused rather often, and when given
    // it is mostly within a few decimetres horizontally.
    EXPECT_GT(all.valid_tdoa, all.windows * 55 / 100);
    EXPECT_GT(all.valid_us, all.windows * 55 / 100);
    EXPECT_LT(quantile(all.horizontal_tdoa, 0.5), 0.35);
    EXPECT_LT(quantile(all.horizontal_us, 0.5), 0.35);
    EXPECT_LT(quantile(all.horizontal_us, 0.9), 1.0);
  }
}

// ---------------------------------------------------------------------------
// Degenerate geometry

TEST(TdoaFixDegenerate, ThreeAnchorsAreNotEnoughEvenWithTheBand) {
  const std::vector<Vec3> all = sim::defaultOfficeAnchors();
  const std::vector<Vec3> three = {all[0], all[1], all[2]};
  RowOptions o;
  o.sigma_m = 0.05;
  const std::vector<TdoaSample> rows = tdoaRows(three, Vec3(0.5, -1.0, 1.3), 900, o);
  const TdoaFix fix = locateTdoa(rows, {}, 0, three, fixParams());
  EXPECT_FALSE(fix.valid);
  EXPECT_EQ(fix.failure, TdoaFixFailure::kTooFewAnchors);
  EXPECT_NE(fix.message.find("3 anchors heard (2 independent differences)"), std::string::npos) << fix.message;
  EXPECT_NE(fix.message.find("need 4"), std::string::npos) << fix.message;

  const TdoaFix empty = locateTdoa({}, {}, 0, all, fixParams());
  EXPECT_FALSE(empty.valid);
  EXPECT_EQ(empty.failure, TdoaFixFailure::kTooFewAnchors);
}

TEST(TdoaFixDegenerate, TagInThePlaneOfCoplanarAnchors) {
  // Anchors all at 1.6 m, the tag at 1.6 m: TDoA says nothing about its height.
  const std::vector<Vec3> anchors = {{-6, -5, 1.6}, {6, -5, 1.6}, {6, 5, 1.6}, {-6, 5, 1.6},
                                     {0, -5.5, 1.6}, {7, 0, 1.6},  {0, 5.5, 1.6}, {-7, 0, 1.6}};
  const Vec3 p(1.0, -1.5, 1.6);
  RowOptions o;
  o.sigma_m = 0.05;
  const std::vector<TdoaSample> rows = tdoaRows(anchors, p, 1000, o);

  TdoaFixParams no_band = fixParams(0.05);
  no_band.band = HeightBand::off();
  const TdoaFix fail = locateTdoa(rows, {}, 0, anchors, no_band);
  EXPECT_FALSE(fail.valid);
  EXPECT_EQ(fail.failure, TdoaFixFailure::kPoorGeometry) << fail.message;
  EXPECT_NE(fail.message.find("height is unobservable"), std::string::npos) << fail.message;
  EXPECT_LT((fail.p_w_tag.head<2>() - p.head<2>()).norm(), 0.1);  // the horizontal part is still good

  const TdoaFix fix = locateTdoa(rows, {}, 0, anchors, fixParams(0.05));
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_TRUE(fix.height_from_band);
  EXPECT_LT((fix.p_w_tag.head<2>() - p.head<2>()).norm(), 0.1) << fix.message;
  EXPECT_GE(fix.p_w_tag.z(), 0.9);
  EXPECT_LE(fix.p_w_tag.z(), 1.9);
  EXPECT_GT(std::sqrt(fix.cov_p(2, 2)), 0.2);  // honest about the height: the band's width
  EXPECT_NE(fix.message.find("from the band"), std::string::npos) << fix.message;
}

TEST(TdoaFixDegenerate, CeilingAnchorsMirrorNeedsTheBand) {
  const std::vector<Vec3> anchors = {{-5, -5, 2.7}, {5, -5, 2.7}, {5, 5, 2.7}, {-5, 5, 2.7}, {0, 0, 2.7}, {0, 5, 2.7}};
  const Vec3 p(1.0, 1.5, 1.2);
  RowOptions o;
  o.sigma_m = 0.05;
  const std::vector<TdoaSample> rows = tdoaRows(anchors, p, 1100, o);
  const TdoaFix fix = locateTdoa(rows, {}, 0, anchors, fixParams(0.05));
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_LT((fix.p_w_tag - p).norm(), 0.2) << fix.message;
  EXPECT_FALSE(fix.mirror_ambiguous);

  TdoaFixParams no_band = fixParams(0.05);
  no_band.band = HeightBand::off();
  const TdoaFix amb = locateTdoa(rows, {}, 0, anchors, no_band);
  EXPECT_FALSE(amb.valid);
  EXPECT_TRUE(amb.mirror_ambiguous) << amb.message;
  EXPECT_EQ(amb.failure, TdoaFixFailure::kAmbiguous);
  EXPECT_NE(amb.message.find("ambiguous"), std::string::npos) << amb.message;
}

TEST(TdoaFixDegenerate, CollinearAnchors) {
  const std::vector<Vec3> line = {{-6, 0, 2}, {-3, 0, 2}, {0, 0, 2}, {3, 0, 2}, {6, 0, 2}};
  RowOptions o;
  const std::vector<TdoaSample> rows = tdoaRows(line, Vec3(1, 2, 1.3), 1200, o);
  const TdoaFix fix = locateTdoa(rows, {}, 0, line, fixParams());
  EXPECT_FALSE(fix.valid);
  EXPECT_EQ(fix.failure, TdoaFixFailure::kDegenerateGeometry) << fix.message;
  EXPECT_NE(fix.message.find("collinear"), std::string::npos) << fix.message;
}

TEST(TdoaFixDegenerate, AbsurdDifferencesGiveAPoorFixNotAThrow) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  std::vector<TdoaSample> rows = tdoaRows(anchors, Vec3(0, 0, 1.2), 1300, RowOptions{});
  std::mt19937_64 rng(1301);
  std::uniform_real_distribution<double> u(-15.0, 15.0);
  for (TdoaSample& s : rows) s.diff_m = u(rng);
  const TdoaFix fix = locateTdoa(rows, {}, 0, anchors, fixParams());
  EXPECT_FALSE(fix.valid);
  EXPECT_NE(fix.failure, TdoaFixFailure::kNone);
  EXPECT_FALSE(fix.message.empty());
}

// ---------------------------------------------------------------------------
// Malformed input

TEST(TdoaFixInput, MalformedRowsThrowNamingTheField) {
  std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  const std::vector<TdoaSample> good = tdoaRows(anchors, Vec3(0, 0, 1.2), 1400, RowOptions{});
  const TdoaFixParams params = fixParams();
  auto with = [&](auto edit) {
    std::vector<TdoaSample> rows = good;
    edit(rows);
    return [rows, &anchors, &params] { locateTdoa(rows, {}, 0, anchors, params); };
  };
  expectThrowsNaming(with([](auto& r) { r[2].anchor_b = 99; }), "tdoa[2].anchor_b = 99: unknown anchor id");
  expectThrowsNaming(with([](auto& r) { r[3].anchor_a = 8; }), "tdoa[3].anchor_a");
  expectThrowsNaming(with([](auto& r) { r[4].anchor_a = r[4].anchor_b; }), "tdoa[4]: anchor_a == anchor_b");
  expectThrowsNaming(with([](auto& r) { r[1].diff_m = std::nan(""); }), "tdoa[1].diff_m");
  expectThrowsNaming(with([](auto& r) { r[1].diff_m = INFINITY; }), "tdoa[1].diff_m");

  std::vector<UltrasonicSample> us(2);
  us[0].anchor_id = 1;
  us[0].range_m = 3.0;
  us[1].anchor_id = 42;
  expectThrowsNaming([&] { locateTdoa(good, us, 0, anchors, params); }, "ultrasonic[1].anchor_id");
  us[1].anchor_id = 2;
  us[1].range_m = std::nan("");
  expectThrowsNaming([&] { locateTdoa(good, us, 0, anchors, params); }, "ultrasonic[1].range_m");
  us[1].range_m = -1.0;
  expectThrowsNaming([&] { locateTdoa(good, us, 0, anchors, params); }, "ultrasonic[1].range_m is negative");

  std::vector<Vec3> bad_anchors = anchors;
  bad_anchors[good[0].anchor_b] = Vec3(NAN, 0, 0);
  expectThrowsNaming([&] { locateTdoa(good, {}, 0, bad_anchors, params); },
                    "p_w_anchors[" + std::to_string(good[0].anchor_b) + "]");
  bad_anchors = anchors;
  bad_anchors[good[0].anchor_a] = bad_anchors[good[0].anchor_b];
  expectThrowsNaming([&] { locateTdoa(good, {}, 0, bad_anchors, params); }, "tdoa[0]: anchor_a and anchor_b");
}

TEST(TdoaFixInput, InvalidParamsThrowNamingTheField) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  auto check = [&](auto edit, const std::string& field) {
    TdoaFixParams p;
    edit(p);
    expectThrowsNaming([&] { p.validate(); }, "TdoaFixParams." + field);
    expectThrowsNaming([&] { locateTdoa({}, {}, 0, anchors, p); }, "TdoaFixParams." + field);
  };
  check([](TdoaFixParams& p) { p.sigma_m = 0.0; }, "sigma_m");
  check([](TdoaFixParams& p) { p.sigma_m = NAN; }, "sigma_m");
  check([](TdoaFixParams& p) { p.ultrasonic_sigma_m = -1.0; }, "ultrasonic_sigma_m");
  check([](TdoaFixParams& p) { p.ultrasonic_offset_m = -0.1; }, "ultrasonic_offset_m");
  check([](TdoaFixParams& p) { p.min_anchors = 3; }, "min_anchors");
  check([](TdoaFixParams& p) { p.max_hypotheses = 0; }, "max_hypotheses");
  check([](TdoaFixParams& p) { p.refine_candidates = 0; }, "refine_candidates");
  check([](TdoaFixParams& p) { p.min_inlier_fraction = 1.5; }, "min_inlier_fraction");
  check([](TdoaFixParams& p) { p.max_pdop = 0.0; }, "max_pdop");
  check([](TdoaFixParams& p) { p.band.max_height_m = 0.5; }, "band.max_height_m");
}

}  // namespace
}  // namespace rilo
