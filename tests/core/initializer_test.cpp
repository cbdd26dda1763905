// Initialization without a known start: strapdown integration, gravity
// alignment, multilateration, range-inertial yaw alignment, the Initializer
// (the Ranging-IMU Fusion paper's batch window) on simulated walks (moving and still starts, 40 Hz
// and 1 Hz ranging, 25 % NLOS), garbage input, and the hand-over to the
// online estimator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <numeric>
#include <random>

#include "estimation/init/initializer.h"
#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/tracking/hand_over.h"
#include "estimation/tracking/range_imu_estimator.h"
#include "sim/range_imu_scenario.h"
#include "support/initializer_scenarios.h"
#include "support/online_run.h"

namespace rilo {
namespace {

using testing::movingScenario;
InitializerParams paramsFor(const sim::Scenario& s) { return testing::initializerParamsFor(s); }

constexpr double kDeg = M_PI / 180.0;

// ---------------------------------------------------------------------------
// Scenarios

/// A LissajousWalk that first stands still for `still_s`, then speeds up
/// smoothly (C1 time warp over `ramp_s`) into the walk: tau(t) = 0 while
/// still, tau' rises from 0 to 1 as 3x^2 - 2x^3. Exact derivatives:
/// v = v_walk tau', a = a_walk tau'^2 + v_walk tau'', omega = omega_walk tau'.
class StillThenWalk final : public sim::Trajectory {
 public:
  StillThenWalk(double still_s, double ramp_s) : still_s_(still_s), ramp_s_(ramp_s) {}
  sim::KinematicState at(double t) const override {
    double tau = 0.0, d1 = 0.0, d2 = 0.0;
    if (t > still_s_ && t < still_s_ + ramp_s_) {
      const double x = (t - still_s_) / ramp_s_;
      tau = ramp_s_ * (x * x * x - 0.5 * x * x * x * x);
      d1 = 3.0 * x * x - 2.0 * x * x * x;
      d2 = (6.0 * x - 6.0 * x * x) / ramp_s_;
    } else if (t >= still_s_ + ramp_s_) {
      tau = 0.5 * ramp_s_ + (t - still_s_ - ramp_s_);
      d1 = 1.0;
    }
    const sim::KinematicState w = walk_.at(tau);
    sim::KinematicState s;
    s.T_w_b = w.T_w_b;
    s.v_w = w.v_w * d1;
    s.a_w = w.a_w * d1 * d1 + w.v_w * d2;
    s.omega_b = w.omega_b * d1;
    return s;
  }

 private:
  sim::LissajousWalk walk_;
  double still_s_, ramp_s_;
};

/// sim::simulateScenario's sensor models (noisy biased IMU, persistent NLOS
/// Markov chains, strongest-anchor selection, outliers, dropouts) on any
/// trajectory: simulateScenario itself always walks the LissajousWalk, which
/// is moving at t = 0.
sim::Scenario simulateOn(std::shared_ptr<const sim::Trajectory> truth, const sim::ScenarioParams& p) {
  sim::Scenario s;
  s.params = p;
  s.p_w_anchors = sim::defaultOfficeAnchors();
  s.p_b_tag = Eigen::Vector3d(0.05, 0.0, 0.08);
  s.truth = std::move(truth);
  s.t0_ns = 1'000'000'000;
  std::mt19937_64 rng(p.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto randn3 = [&] { return Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); };
  Eigen::Vector3d b_g = p.gyro_bias_init_sigma * randn3(), b_a = p.accel_bias_init_sigma * randn3();
  s.gyro_bias0 = b_g;
  s.accel_bias0 = b_a;
  const double dt_imu = 1.0 / p.imu_rate_hz;
  const auto n_imu = static_cast<std::int64_t>(std::floor(p.duration_s * p.imu_rate_hz)) + 1;
  for (std::int64_t k = 0; k < n_imu; ++k) {
    const double t = static_cast<double>(k) * dt_imu;
    const sim::ImuReading m = sim::idealImu(s.truth->at(t), p.gravity_m_s2);
    ImuSample smp;
    smp.t_ns = s.t0_ns + std::llround(t * 1e9);
    smp.gyro_rad_s = m.gyro + b_g + p.gyro_noise_density / std::sqrt(dt_imu) * randn3();
    smp.accel_m_s2 = m.accel + b_a + p.accel_noise_density / std::sqrt(dt_imu) * randn3();
    s.imu.push_back(smp);
    Eigen::Matrix<double, 6, 1> b;
    b << b_a, b_g;
    s.imu_bias_truth.push_back(b);
    b_g += p.gyro_bias_walk * std::sqrt(dt_imu) * randn3();
    b_a += p.accel_bias_walk * std::sqrt(dt_imu) * randn3();
  }
  const std::size_t n_anchors = s.p_w_anchors.size();
  std::vector<bool> nlos(n_anchors, false);
  std::vector<double> nlos_bias(n_anchors, 0.0);
  const double dt_range = 1.0 / p.range_rate_hz;
  const double p_exit = std::min(1.0, dt_range * p.ranges_per_cycle / p.nlos_mean_duration_s);
  const double p_enter = p_exit * p.nlos_fraction / std::max(1e-9, 1.0 - p.nlos_fraction);
  auto halfCauchy = [&](double scale) { return scale * std::abs(std::tan(M_PI * (u01(rng) - 0.5))); };
  const double cycle_s = dt_range * p.ranges_per_cycle;
  for (double t_cycle = 0.0; t_cycle + cycle_s <= p.duration_s; t_cycle += cycle_s) {
    for (std::size_t a = 0; a < n_anchors; ++a) {
      if (nlos[a]) {
        if (u01(rng) < p_exit) nlos[a] = false;
        nlos_bias[a] = std::min(p.nlos_max_excess_m, std::max(0.0, nlos_bias[a] + 0.05 * n01(rng)));
      } else if (u01(rng) < p_enter) {
        nlos[a] = true;
        nlos_bias[a] = std::min(p.nlos_max_excess_m, halfCauchy(p.nlos_scale_m));
      }
    }
    const Eigen::Vector3d p_now = s.truth->at(t_cycle).T_w_b.p;
    std::vector<std::size_t> order(n_anchors);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) {
      return (s.p_w_anchors[i] - p_now).norm() + (nlos[i] ? 3.0 : 0.0) <
             (s.p_w_anchors[j] - p_now).norm() + (nlos[j] ? 3.0 : 0.0);
    });
    for (int k = 0; k < p.ranges_per_cycle && static_cast<std::size_t>(k) < n_anchors; ++k) {
      const double t = t_cycle + k * dt_range;
      if (u01(rng) < p.range_dropout) continue;
      const std::size_t a = order[static_cast<std::size_t>(k)];
      const double true_range = (s.truth->at(t).T_w_b.transformFrom(s.p_b_tag) - s.p_w_anchors[a]).norm();
      double excess = p.range_sigma_m * n01(rng);
      if (nlos[a]) excess += nlos_bias[a];
      if (u01(rng) < p.outlier_probability) excess += std::min(p.nlos_max_excess_m, halfCauchy(1.5));
      RangeSample r;
      r.t_ns = s.t0_ns + std::llround(t * 1e9);
      r.anchor_id = static_cast<std::uint32_t>(a);
      r.range_m = std::max(0.0, true_range + excess);
      r.los = nlos[a] ? 0 : 1;
      s.ranges.push_back(r);
    }
  }
  return s;
}

sim::Scenario stillStartScenario(std::uint64_t seed, double range_rate_hz, double duration_s, double still_s = 4.0) {
  sim::ScenarioParams sp;
  sp.seed = seed;
  sp.range_rate_hz = range_rate_hz;
  sp.duration_s = duration_s;
  return simulateOn(std::make_shared<StillThenWalk>(still_s, 2.0), sp);
}

// ---------------------------------------------------------------------------
// Running and scoring

struct InitRun {
  bool initialized = false;
  double time_s = 0.0;  ///< data time to initialize (s)
  double pos_err_m = 0.0, h_err_m = 0.0, v_err_m = 0.0;
  double tilt_err_deg = 0.0, yaw_err_deg = 0.0, vel_err_m_s = 0.0;
  std::string status;
};

double tiltErrorDeg(const Mat3& R_est, const Mat3& R_true) {
  const Vec3 a = R_est.transpose() * Vec3::UnitZ(), b = R_true.transpose() * Vec3::UnitZ();
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) / kDeg;
}
double yawErrorDeg(const Mat3& R_est, const Mat3& R_true) {
  const Mat3 E = R_est * R_true.transpose();
  return std::abs(std::atan2(E(1, 0), E(0, 0))) / kDeg;
}

/// Feeds the scenario in time order (a range before an IMU sample of the
/// same time), calling process() after every IMU sample, until initialized
/// or the data ends. `on_imu` (optional) sees the initializer after each IMU sample.
InitRun runInit(const sim::Scenario& s, Initializer& init,
                const std::function<void(const Initializer&, const ImuSample&)>& on_imu = {}) {
  std::size_t i = 0, r = 0;
  while ((i < s.imu.size() || r < s.ranges.size()) && !init.initialized()) {
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      init.addRange(s.ranges[r++]);
    } else {
      init.addImu(s.imu[i]);
      init.process();
      if (on_imu) on_imu(init, s.imu[i]);
      ++i;
    }
  }
  InitRun out;
  out.initialized = init.initialized();
  out.status = init.status().message;
  if (!out.initialized) return out;
  const InitResult& res = init.result();
  const sim::KinematicState truth = s.truthAt(res.state.t_ns);
  const Vec3 dp = res.state.T_w_b.p - truth.T_w_b.p;
  out.time_s = res.time_to_init_s;
  out.pos_err_m = dp.norm();
  out.h_err_m = dp.head<2>().norm();
  out.v_err_m = std::abs(dp.z());
  out.tilt_err_deg = tiltErrorDeg(res.state.T_w_b.R, truth.T_w_b.R);
  out.yaw_err_deg = yawErrorDeg(res.state.T_w_b.R, truth.T_w_b.R);
  out.vel_err_m_s = (res.state.v_w - truth.v_w).norm();
  return out;
}

void printRun(const char* what, std::uint64_t seed, const InitRun& r) {
  std::printf("%-13s seed %2llu: %s t=%5.1f s  pos %.2f m (h %.2f v %.2f)  tilt %.2f deg  yaw %.2f deg  vel %.2f m/s\n",
              what, static_cast<unsigned long long>(seed), r.initialized ? "ok  " : "FAIL", r.time_s, r.pos_err_m,
              r.h_err_m, r.v_err_m, r.tilt_err_deg, r.yaw_err_deg, r.vel_err_m_s);
  if (!r.initialized) std::printf("    status: %s\n", r.status.c_str());
}

struct Tally {
  int runs = 0, initialized = 0, pos = 0, h = 0, tilt = 0, yaw = 0, vel = 0;
  void add(const InitRun& r, double pos_limit_m) {
    ++runs;
    if (!r.initialized) return;
    ++initialized;
    pos += r.pos_err_m < pos_limit_m;
    h += r.h_err_m < pos_limit_m;
    tilt += r.tilt_err_deg < 2.0;
    yaw += r.yaw_err_deg < 10.0;
    vel += r.vel_err_m_s < 0.3;
  }
};

// ---------------------------------------------------------------------------
// Strapdown integration

TEST(InitStrapdown, PropagatesTheTrueStateAlongTheWalk) {
  const sim::Scenario s = movingScenario(3, 40.0, 8.0);
  const std::int64_t t0 = s.t0_ns + 500'000'000;
  const std::vector<std::int64_t> q = {t0, t0 + 1'000'000'000, t0 + 3'000'000'000, t0 + 6'000'000'000};
  const std::vector<StrapdownDelta> d = integrateStrapdown(s.imu, t0, q);
  ASSERT_EQ(d.size(), q.size());
  const sim::KinematicState st0 = s.truthAt(t0);
  const ImuBias b(s.accel_bias0, s.gyro_bias0);
  for (std::size_t k = 0; k < d.size(); ++k) {
    EXPECT_EQ(d[k].t_ns, q[k]);
    const StrapdownState ps = propagate(d[k], st0.T_w_b, st0.v_w, b, s.params.gravity_m_s2);
    const sim::KinematicState st = s.truthAt(q[k]);
    EXPECT_LT((ps.T_w_b.p - st.T_w_b.p).norm(), 0.15) << "t+" << d[k].dt_s;
    EXPECT_LT(so3::log(ps.T_w_b.R.transpose() * st.T_w_b.R).norm(), 0.3 * kDeg);
    EXPECT_LT((ps.v_w - st.v_w).norm(), 0.05);
  }
  EXPECT_TRUE(integrateStrapdown({}, t0, q).empty());
}

TEST(InitStrapdown, BiasJacobiansMatchReintegration) {
  // Integrating samples with a bias removed must equal the first-order correction.
  const sim::Scenario s = movingScenario(4, 40.0, 4.0);
  const ImuBias db(Vec3(0.02, -0.03, 0.01), Vec3(1e-3, -2e-3, 1.5e-3));
  std::vector<ImuSample> shifted = s.imu;
  for (ImuSample& m : shifted) {
    m.accel_m_s2 -= db.accel;
    m.gyro_rad_s -= db.gyro;
  }
  const std::int64_t t0 = s.t0_ns, t1 = s.t0_ns + 3'000'000'000;
  const StrapdownDelta d = integrateStrapdown(s.imu, t0, {t1}).front();
  const StrapdownDelta e = integrateStrapdown(shifted, t0, {t1}).front();
  const StrapdownDelta::Corrected c = d.corrected(db);
  // Residuals are second order in the bias (the uncorrected difference is ~10x larger).
  EXPECT_LT(so3::log(c.dR.transpose() * e.dR).norm(), 0.05 * so3::log(d.dR.transpose() * e.dR).norm());
  EXPECT_LT((c.dv - e.dv).norm(), 0.05 * (d.dv - e.dv).norm());
  EXPECT_LT((c.dp - e.dp).norm(), 0.05 * (d.dp - e.dp).norm());
}

TEST(InitStrapdown, QueriesBetweenSamplesSplitTheHold) {
  std::vector<ImuSample> imu(3);
  for (int k = 0; k < 3; ++k) {
    imu[static_cast<std::size_t>(k)].t_ns = 1000 + 10'000'000LL * k;
    imu[static_cast<std::size_t>(k)].accel_m_s2 = Vec3(1.0 + k, 0.0, 9.81);
  }
  // 5 ms into the second sample's hold: 10 ms of a=1 then 5 ms of a=2.
  const StrapdownDelta d = integrateStrapdown(imu, 1000, {1000 + 15'000'000}).front();
  EXPECT_NEAR(d.dv.x(), 0.010 * 1.0 + 0.005 * 2.0, 1e-12);
  EXPECT_NEAR(d.dt_s, 0.015, 1e-12);
}

// ---------------------------------------------------------------------------
// Gravity alignment

std::vector<ImuSample> stillImu(const Mat3& R_w_b, double seconds, std::uint64_t seed, const Vec3& accel_bias) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<ImuSample> imu;
  const Vec3 f = R_w_b.transpose() * Vec3(0.0, 0.0, 9.81);
  for (int k = 0; k < static_cast<int>(seconds * 800.0); ++k) {
    ImuSample m;
    m.t_ns = 1'000'000'000 + 1'250'000LL * k;
    m.accel_m_s2 = f + accel_bias + 0.045 * Vec3(n01(rng), n01(rng), n01(rng));
    m.gyro_rad_s = Vec3(1e-3, -2e-3, 5e-4) + 0.008 * Vec3(n01(rng), n01(rng), n01(rng));
    imu.push_back(m);
  }
  return imu;
}

TEST(InitGravity, StillDeviceGivesRollAndPitch) {
  const Mat3 R = (Eigen::AngleAxisd(1.0, Vec3::UnitZ()) * Eigen::AngleAxisd(0.3, Vec3::UnitY()) *
                  Eigen::AngleAxisd(-0.2, Vec3::UnitX()))
                     .toRotationMatrix();
  const std::vector<ImuSample> imu = stillImu(R, 2.0, 1, Vec3(0.02, -0.01, 0.03));
  const GravityAlignment g = alignGravity(imu, imu.front().t_ns, imu.back().t_ns, 9.81);
  ASSERT_TRUE(g.valid) << g.message;
  EXPECT_TRUE(g.still) << g.message;
  EXPECT_LT(tiltErrorDeg(g.R_w_b, R), 0.3);
  EXPECT_NEAR(yawOf(g.R_w_b), 0.0, 1e-9);
  EXPECT_LE(g.tilt_sigma_rad, 0.02);
}

TEST(InitGravity, MovingDeviceAveragesTheMotionOut) {
  const sim::Scenario s = movingScenario(2, 40.0, 12.0);
  const std::int64_t t0 = s.t0_ns, t1 = s.t0_ns + 10'000'000'000;
  const GravityAlignment g = alignGravity(s.imu, t0, t1, 9.81);
  ASSERT_TRUE(g.valid) << g.message;
  EXPECT_FALSE(g.still);
  EXPECT_NE(g.message.find("moving"), std::string::npos) << g.message;
  EXPECT_LT(tiltErrorDeg(g.R_w_b, s.truthAt(t0).T_w_b.R), 2.0);
  EXPECT_GT(g.tilt_sigma_rad, 0.01);
}

TEST(InitGravity, NoGravityOrNoSamplesIsReportedNotThrown) {
  std::vector<ImuSample> imu = stillImu(Mat3::Identity(), 1.0, 2, Vec3::Zero());
  for (ImuSample& m : imu) m.accel_m_s2.setZero();  // a dead accelerometer
  const GravityAlignment g = alignGravity(imu, imu.front().t_ns, imu.back().t_ns, 9.81);
  EXPECT_FALSE(g.valid);
  EXPECT_NE(g.message.find("does not measure gravity"), std::string::npos) << g.message;
  EXPECT_FALSE(alignGravity({}, 0, 1'000'000'000, 9.81).valid);
  EXPECT_FALSE(alignGravity(imu, 5, 5, 9.81).valid);
  GravityParams bad;
  bad.still_block_s = 0.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Multilateration

std::vector<RangeSample> rangesTo(const std::vector<Vec3>& anchors, const Vec3& p0, const Vec3& v, double seconds,
                                  double rate_hz, std::uint64_t seed, double sigma = 0.1) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<RangeSample> out;
  for (int k = 0; k < static_cast<int>(seconds * rate_hz); ++k) {
    RangeSample r;
    r.t_ns = 1'000'000'000 + std::llround(k / rate_hz * 1e9);
    r.anchor_id = static_cast<std::uint32_t>(k % static_cast<int>(anchors.size()));
    const Vec3 p = p0 + v * (1e-9 * static_cast<double>(r.t_ns - 1'000'000'000));
    r.range_m = (p - anchors[r.anchor_id]).norm() + sigma * n01(rng);
    out.push_back(r);
  }
  return out;
}

MultilaterationParams fixParams() {
  MultilaterationParams p;
  p.sigma_m = 0.1;
  return p;
}

TEST(InitMultilateration, MovingTagWithOneNlosAnchor) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  const Vec3 p0(1.0, -2.0, 1.3), v(1.0, 0.6, 0.0);
  std::vector<RangeSample> r = rangesTo(anchors, p0, v, 1.0, 40.0, 5);
  for (RangeSample& x : r) {
    if (x.anchor_id == 2) x.range_m += 1.5;  // persistent NLOS: always too long
  }
  const TagFix fix = multilaterate(r, r.front().t_ns, anchors, fixParams());
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_LT((fix.p_w_tag - p0).norm(), 0.25);
  EXPECT_LT((fix.v_w - v).norm(), 0.3);
  EXPECT_EQ(fix.anchors_heard, 8);
  EXPECT_EQ(fix.anchors_used, 7);  // the NLOS anchor has no inlier
  EXPECT_LT(fix.rms_m, 0.2);
  EXPECT_LT(fix.pdop, 4.0);
}

TEST(InitMultilateration, CeilingAnchorsMirrorResolvedByHeightBand) {
  // Anchors nearly coplanar at 2.5-2.7 m: the mirror above the ceiling fits as well.
  const std::vector<Vec3> anchors = {{-5, -5, 2.5}, {5, -5, 2.6}, {5, 5, 2.7}, {-5, 5, 2.55}, {0, 0, 2.65}};
  const Vec3 p0(1.0, 1.5, 1.2);
  const std::vector<RangeSample> r = rangesTo(anchors, p0, Vec3::Zero(), 1.0, 40.0, 6, 0.05);
  const TagFix fix = multilaterate(r, r.front().t_ns, anchors, fixParams());
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_LT((fix.p_w_tag - p0).norm(), 0.3);
  EXPECT_FALSE(fix.mirror_ambiguous);

  MultilaterationParams no_band = fixParams();
  no_band.band.enabled = false;
  no_band.fit_velocity = false;
  const TagFix amb = multilaterate(r, r.front().t_ns, anchors, no_band);
  EXPECT_TRUE(amb.mirror_ambiguous) << amb.message;
  EXPECT_FALSE(amb.valid);
  EXPECT_NE(amb.message.find("ambiguous"), std::string::npos) << amb.message;
}

TEST(InitMultilateration, ThreeAnchorsNeedTheBandTwoAreNotEnough) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  const std::vector<Vec3> three = {anchors[0], anchors[1], anchors[2]};
  const Vec3 p0(0.5, -1.0, 1.3);
  const std::vector<RangeSample> r3 = rangesTo(three, p0, Vec3::Zero(), 1.0, 40.0, 7, 0.05);
  const TagFix fix3 = multilaterate(r3, r3.front().t_ns, three, fixParams());
  ASSERT_TRUE(fix3.valid) << fix3.message;
  EXPECT_LT((fix3.p_w_tag - p0).norm(), 0.4);

  MultilaterationParams no_band = fixParams();
  no_band.band.enabled = false;
  const TagFix fix3nb = multilaterate(r3, r3.front().t_ns, three, no_band);
  EXPECT_FALSE(fix3nb.valid);
  EXPECT_NE(fix3nb.message.find("3 anchors heard, need 4"), std::string::npos) << fix3nb.message;

  const std::vector<Vec3> two = {anchors[0], anchors[1]};
  const std::vector<RangeSample> r2 = rangesTo(two, p0, Vec3::Zero(), 1.0, 40.0, 8);
  const TagFix fix2 = multilaterate(r2, r2.front().t_ns, two, fixParams());
  EXPECT_FALSE(fix2.valid);
  EXPECT_NE(fix2.message.find("2 anchors heard, need 4"), std::string::npos) << fix2.message;
  EXPECT_FALSE(multilaterate({}, 0, anchors, fixParams()).valid);
}

// Anchors far away and near the tag's height (a large hall, a flight arena):
// height is weakly determined by them (PDOP over 10), but the band holds it,
// so the fix is sound. Anchors in a line leave the side of the line open:
// refused with the band too.
TEST(InitMultilateration, TheBandHoldsTheHeightFarAnchorsLeaveOpen) {
  const std::vector<Vec3> anchors = {{-20, -15, 2.0}, {20, -15, 2.2}, {20, 15, 1.9}, {-20, 15, 2.1}, {0, 18, 2.0}};
  const Vec3 p0(2.0, 1.0, 1.5);
  const std::vector<RangeSample> r = rangesTo(anchors, p0, Vec3::Zero(), 3.0, 10.0, 11, 0.05);
  MultilaterationParams still = fixParams();
  still.fit_velocity = false;
  const TagFix fix = multilaterate(r, r.front().t_ns, anchors, still);
  ASSERT_TRUE(fix.valid) << fix.message;
  EXPECT_LT((fix.p_w_tag - p0).head<2>().norm(), 0.2);
  EXPECT_TRUE(still.band.contains(fix.p_w_tag.z(), 0.0));
  MultilaterationParams no_band = still;
  no_band.band.enabled = false;
  const TagFix open = multilaterate(r, r.front().t_ns, anchors, no_band);
  EXPECT_GT(open.pdop, no_band.max_pdop) << open.message;
  EXPECT_FALSE(open.valid);
  EXPECT_NE(open.message.find("PDOP"), std::string::npos) << open.message;

  // A corridor: four anchors along a line at one height (0.15 m across it),
  // the tag 1-3 m to the side. Whatever the band says, the side is open:
  // no fix on either side is accepted (a review's case: with the band's
  // credit and no spread check, 8 of 54 were accepted 2.4-5.8 m off).
  const std::vector<Vec3> corridor = {{-15, 0.1, 2.5}, {-5, -0.15, 2.5}, {5, 0.15, 2.5}, {15, -0.1, 2.5}};
  MultilaterationParams credit_anyway = still;
  credit_anyway.min_band_credit_spread_ratio = 0.0;
  int accepted = 0, accepted_without_check = 0, wrong_side_without_check = 0;
  for (int k = 0; k < 18; ++k) {
    const double side = (k % 2 == 0) ? 1.0 : -1.0;
    const Vec3 p(-8.0 + 1.0 * k, side * (1.0 + 0.25 * (k % 9)), 1.4);
    const std::vector<RangeSample> rc = rangesTo(corridor, p, Vec3::Zero(), 3.0, 10.0, 20 + k, 0.1);
    accepted += multilaterate(rc, rc.front().t_ns, corridor, still).valid ? 1 : 0;
    const TagFix f = multilaterate(rc, rc.front().t_ns, corridor, credit_anyway);
    accepted_without_check += f.valid ? 1 : 0;
    wrong_side_without_check += f.valid && f.p_w_tag.y() * p.y() < 0.0 ? 1 : 0;
  }
  std::printf("corridor: %d of 18 fixes accepted (%d with the band's credit regardless of spread, %d of them on the "
              "wrong side)\n", accepted, accepted_without_check, wrong_side_without_check);
  EXPECT_EQ(accepted, 0);
  EXPECT_GT(wrong_side_without_check, 0) << "the case the spread check is for";
}

TEST(InitMultilateration, AbsurdRangesGiveAPoorFixNotAThrow) {
  const std::vector<Vec3> anchors = sim::defaultOfficeAnchors();
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.0, 40.0);
  std::vector<RangeSample> r = rangesTo(anchors, Vec3(0, 0, 1.2), Vec3::Zero(), 1.0, 40.0, 9);
  for (RangeSample& x : r) x.range_m = u(rng);
  r[3].anchor_id = 99;  // unknown anchor: skipped
  r[4].range_m = std::nan("");
  const TagFix fix = multilaterate(r, r.front().t_ns, anchors, fixParams());
  EXPECT_FALSE(fix.valid);
  EXPECT_EQ(fix.ranges, static_cast<int>(r.size()) - 2);
  EXPECT_FALSE(fix.message.empty());
}

// ---------------------------------------------------------------------------
// Range-inertial alignment

AlignmentParams alignmentParamsFor(const sim::Scenario& s) {
  AlignmentParams p;
  p.range_sigma_m = s.params.range_sigma_m;
  p.p_b_tag = s.p_b_tag;
  p.accel_bias_sigma = 3.0 * s.params.accel_bias_init_sigma;
  p.gyro_bias_sigma = 3.0 * s.params.gyro_bias_init_sigma;
  return p;
}

TEST(InitAlignment, FindsYawFromAnyStartOnceTheWalkHasTurned) {
  const sim::Scenario s = movingScenario(5, 40.0, 26.0);
  const std::int64_t t0 = s.ranges.front().t_ns, t1 = t0 + 25'000'000'000;
  std::vector<RangeSample> r;
  for (const RangeSample& x : s.ranges) {
    if (x.t_ns <= t1) r.push_back(x);
  }
  const GravityAlignment g = alignGravity(s.imu, t0, t1, 9.81);
  ASSERT_TRUE(g.valid);
  const sim::KinematicState st0 = s.truthAt(t0);
  // A rough start (as multilateration gives): 0.5 m and 0.5 m/s off.
  const AlignmentResult a = alignRangeInertial(s.imu, r, t0, s.p_w_anchors, g,
                                               st0.T_w_b.transformFrom(s.p_b_tag) + Vec3(0.4, -0.3, 0.1),
                                               st0.v_w + Vec3(0.3, 0.3, 0.0), alignmentParamsFor(s));
  ASSERT_TRUE(a.valid) << a.message;
  EXPECT_LT(yawErrorDeg(a.T_w_b.R, st0.T_w_b.R), 5.0);
  EXPECT_LT(tiltErrorDeg(a.T_w_b.R, st0.T_w_b.R), 1.0);
  EXPECT_LT((a.T_w_b.p - st0.T_w_b.p).norm(), 0.3);
  EXPECT_LT((a.v_w - st0.v_w).norm(), 0.2);
  EXPECT_LT(a.yaw_sigma_rad, 5.0 * kDeg);
  // At the newest range (the gate's point): the fitted end attitude is as good, and its sigma finite and small.
  EXPECT_LT(a.yaw_sigma_end_rad, 5.0 * kDeg);
  const StrapdownDelta d_end = integrateStrapdown(s.imu, t0, {r.back().t_ns}).front();
  // (3.4 deg here at a 1.0 deg sigma: 25 % NLOS, the robust fit's sigma is optimistic)
  EXPECT_LT(yawErrorDeg(a.at(d_end, 9.81).T_w_b.R, s.truthAt(r.back().t_ns).T_w_b.R), 5.0);
  EXPECT_GT(a.second_cost_gap, 8.0);
  EXPECT_GT(a.moved_m, 3.0);
  EXPECT_EQ(a.hypothesis_costs.size(), 8u);
}

TEST(InitAlignment, StillDeviceLeavesYawUnobservable) {
  const sim::Scenario s = stillStartScenario(6, 40.0, 8.0, 10.0);
  const std::int64_t t0 = s.ranges.front().t_ns, t1 = t0 + 6'000'000'000;
  std::vector<RangeSample> r;
  for (const RangeSample& x : s.ranges) {
    if (x.t_ns <= t1) r.push_back(x);
  }
  const GravityAlignment g = alignGravity(s.imu, t0, t1, 9.81);
  ASSERT_TRUE(g.valid);
  EXPECT_TRUE(g.still);
  const sim::KinematicState st0 = s.truthAt(t0);
  const AlignmentResult a = alignRangeInertial(s.imu, r, t0, s.p_w_anchors, g, st0.T_w_b.transformFrom(s.p_b_tag),
                                               Vec3::Zero(), alignmentParamsFor(s));
  ASSERT_TRUE(a.valid) << a.message;
  EXPECT_GT(a.yaw_sigma_rad, 30.0 * kDeg);  // position and tilt are fine, yaw is anyone's guess
  EXPECT_GT(a.yaw_sigma_end_rad, 30.0 * kDeg);  // at the end as well: no motion, no yaw
  EXPECT_LT(a.moved_m, 0.3);
  EXPECT_LT(tiltErrorDeg(a.T_w_b.R, st0.T_w_b.R), 1.0);
}

TEST(InitAlignment, NoiseScaleFromTheInlierShare) {
  // Exact inverses of P(|N(0, s^2)| <= 3) = share.
  EXPECT_NEAR(noiseScaleFromInlierShare(6827, 10000), 3.0, 1e-3);           // share within 1 sigma: s = 3
  EXPECT_NEAR(noiseScaleFromInlierShare(8664, 10000), 2.0, 2e-3);           // within 1.5 sigma: s = 2
  EXPECT_NEAR(noiseScaleFromInlierShare(9973, 10000), 1.0, 1e-3);           // nominal
  EXPECT_DOUBLE_EQ(noiseScaleFromInlierShare(10, 10), noiseScaleFromInlierShare(99999, 100000));  // clamped: 1
  EXPECT_NEAR(noiseScaleFromInlierShare(10, 10), 1.0, 1e-9);
  EXPECT_NEAR(noiseScaleFromInlierShare(1, 10), 3.0 / 0.6745, 1e-3);      // clamped at a half: 4.45
  EXPECT_DOUBLE_EQ(noiseScaleFromInlierShare(0, 0), 1.0);
  EXPECT_NEAR(noiseScaleFromInlierShare(6827, 10000, 2.0), 2.0, 1e-3);     // another bound
  // Monotonic: fewer inliers, larger scale.
  double prev = 0.0;
  for (int k = 100; k >= 50; k -= 5) {
    const double sc = noiseScaleFromInlierShare(k, 100);
    EXPECT_GE(sc, prev);
    prev = sc;
  }
}

// ---------------------------------------------------------------------------
// The Initializer on whole sessions

TEST(Initializer, MovingStart40HzSeveralSeeds) {
  // The Lissajous walk is smooth (0.2-0.4 m/s^2): yaw separates from the
  // accelerometer bias and tilt only after 15-20 s, so the window grows past
  // the Ranging-IMU Fusion paper's 10 s. Vertical error is dominated by the NLOS bias of weak
  // vertical geometry (the estimator started at the truth has the same), so
  // the 3D bound holds on fewer seeds than the horizontal one.
  Tally t;
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    const sim::Scenario s = movingScenario(seed, 40.0, 35.0);
    Initializer init(s.p_w_anchors, paramsFor(s));
    const InitRun r = runInit(s, init);
    printRun("moving 40 Hz", seed, r);
    t.add(r, 0.3);
    if (r.initialized) {
      const InitResult& res = init.result();
      EXPECT_TRUE(res.lm.converged());
      ASSERT_TRUE(res.window.has_value());
      // Dense ranging: the newest state is handed over (hand_over_sparse_span_s).
      EXPECT_EQ(res.state.index + 1, res.window->graph.state_t_ns.size());
      EXPECT_EQ(res.state.t_ns, res.window->graph.state_t_ns.back());
      EXPECT_EQ(res.window_start_ns, res.window->graph.state_t_ns.front());
      EXPECT_FALSE(res.gravity.still);
      EXPECT_EQ(init.status().state, InitState::kInitialized);
      EXPECT_LT(r.time_s, 30.0);
      EXPECT_GE(init.status().batch_solves, 1);
      EXPECT_LT(init.status().batch_solves, init.status().attempts);  // the alignment gates the expensive step
    }
  }
  EXPECT_EQ(t.initialized, t.runs);
  EXPECT_EQ(t.h, t.runs) << "horizontal < 0.3 m";
  EXPECT_GE(t.pos, t.runs / 2) << "3D < 0.3 m";
  EXPECT_EQ(t.tilt, t.runs) << "roll/pitch < 2 deg";
  EXPECT_GE(t.yaw, t.runs - 2) << "yaw < 10 deg";
  EXPECT_GE(t.vel, t.runs - 1) << "velocity < 0.3 m/s";
}

TEST(Initializer, ATagBeyondTheAnchorsBoxIsNotAccepted) {
  // The walk of the moving scenario moved 13.5 m along x: always 2.5-10.5 m
  // beyond the anchors' box (x in [-7, 7]). The ranges fit, but such a
  // solution is what a mirror across a wall of anchors looks like, so the
  // default refuses it and says why; with the check off the same data
  // initialize.
  sim::ScenarioParams sp;
  sp.seed = 1;
  sp.range_rate_hz = 40.0;
  sp.duration_s = 35.0;
  sim::LissajousWalk::Params walk;
  walk.center.x() = 13.5;
  const sim::Scenario s = simulateOn(std::make_shared<sim::LissajousWalk>(walk), sp);

  // An unused id's placeholder far away must not stretch the box.
  std::vector<Vec3> anchors = s.p_w_anchors;
  anchors.push_back(Vec3::Constant(1e6));
  Initializer strict(anchors, paramsFor(s));
  bool said_why = false;
  const InitRun refused = runInit(s, strict, [&](const Initializer& init, const ImuSample&) {
    said_why |= init.status().message.find("outside the anchors' horizontal box") != std::string::npos;
  });
  EXPECT_FALSE(refused.initialized) << refused.status;
  EXPECT_TRUE(said_why) << refused.status;

  InitializerParams lenient = paramsFor(s);
  lenient.max_outside_anchors_m = std::numeric_limits<double>::infinity();
  Initializer init(s.p_w_anchors, lenient);
  const InitRun r = runInit(s, init);
  EXPECT_TRUE(r.initialized) << r.status;
  EXPECT_LT(r.h_err_m, 1.0) << r.status;
}

TEST(Initializer, NoisierThanNominalDataNeedALargerYawCostGap) {
  // Ranges 2.5x noisier than the graph assumes: every cost, and the gap
  // between two yaws, grows by ~s^2; the accepted alignment must have won by
  // the scaled gap, and the scale must have been seen.
  const sim::Scenario s = movingScenario(2, 40.0, 40.0);
  InitializerParams p = paramsFor(s);
  p.graph.range_noise.sigma_m = s.params.range_sigma_m / 2.5;
  Initializer init(s.p_w_anchors, p);
  bool saw_scaled_wait = false;
  const InitRun r = runInit(s, init, [&](const Initializer& in, const ImuSample&) {
    saw_scaled_wait |= in.status().message.find("at noise scale") != std::string::npos &&
                       in.status().message.find("at noise scale 1.0)") == std::string::npos;
  });
  ASSERT_TRUE(r.initialized) << init.status().message;
  const AlignmentResult& a = init.result().alignment;
  const double sc = std::min(a.noiseScale(), p.max_yaw_gap_noise_scale);
  EXPECT_GT(sc, 1.5);
  EXPECT_GE(a.second_cost_gap, p.min_yaw_cost_gap * sc * sc);
  EXPECT_TRUE(saw_scaled_wait);
}

/// (short, ranges) from a batch summary's "K of N ranges short"; (0, 0) if absent.
std::pair<int, int> shortRangesIn(const std::string& message) {
  int k = 0, n = 0;
  const auto at = message.find(" ranges short");
  if (at == std::string::npos) return {0, 0};
  const auto from = message.rfind(", ", at);
  if (std::sscanf(message.c_str() + from, ", %d of %d", &k, &n) != 2) return {0, 0};
  return {k, n};
}

/// (short, ranges) from an alignment refusal's "M of N ranges inliers, K short"
/// (every measurement a two-way range); (0, 0) if absent.
std::pair<int, int> alignmentShortRangesIn(const std::string& message) {
  int m = 0, n = 0, k = 0;
  const auto at = message.find("ranges inliers, ");
  if (at == std::string::npos) return {0, 0};
  const auto from = message.rfind(", ", at);
  if (std::sscanf(message.c_str() + from, ", %d of %d ranges inliers, %d short", &m, &n, &k) != 3) return {0, 0};
  return {k, n};
}

// Most paths blocked: at the right solution the costs exceed the gates for
// good, but NLOS only lengthens ranges, so few are shorter than the solution
// predicts. After heavy_nlos_after_s the gates widen for such windows.
TEST(Initializer, HeavyNlosStartsOnceItHasWaitedAndFewRangesAreShort) {
  sim::ScenarioParams sp;
  sp.seed = 3;
  sp.range_rate_hz = 40.0;
  sp.duration_s = 80.0;
  sp.nlos_fraction = 0.7;
  sp.nlos_scale_m = 1.0;
  const sim::Scenario s = sim::simulateScenario(sp);

  InitializerParams strict = paramsFor(s);
  strict.heavy_nlos_after_s = std::numeric_limits<double>::infinity();
  Initializer never(s.p_w_anchors, strict);
  bool cost_said = false;
  const InitRun refused = runInit(s, never, [&](const Initializer& in, const ImuSample&) {
    cost_said |= in.status().message.find("disagree with the IMU motion") != std::string::npos ||
                 in.status().message.find("cost too high") != std::string::npos;
  });
  printRun("heavy, off", sp.seed, refused);
  EXPECT_FALSE(refused.initialized) << refused.status;
  EXPECT_TRUE(cost_said) << refused.status;

  InitializerParams p = paramsFor(s);
  p.heavy_nlos_after_s = 30.0;
  Initializer init(s.p_w_anchors, p);
  const InitRun r = runInit(s, init);
  printRun("heavy, 30 s", sp.seed, r);
  ASSERT_TRUE(r.initialized) << r.status;
  EXPECT_GE(r.time_s, p.heavy_nlos_after_s);
  EXPECT_TRUE(init.result().heavy_nlos);
  EXPECT_NE(r.status.find("heavy NLOS"), std::string::npos) << r.status;
  const AlignmentResult& a = init.result().alignment;
  EXPECT_GT(a.ranges, 0);
  EXPECT_LE(a.short_ranges, p.max_short_range_share * a.ranges);
  const auto [batch_short, batch_ranges] = shortRangesIn(r.status);
  ASSERT_GT(batch_ranges, 0) << r.status;
  EXPECT_LE(batch_short, p.max_short_range_share * batch_ranges) << r.status;
  EXPECT_LT(r.h_err_m, 0.5) << r.status;
  EXPECT_LT(r.yaw_err_deg, 10.0) << r.status;
}

// A wrong anchor survey (two anchors swapped) leaves many ranges shorter than
// any solution predicts: the widened gates do not open for it, however wide,
// and the short ranges are what keeps them shut.
TEST(Initializer, SwappedAnchorsAreRefusedAfterTheHeavyNlosWaitToo) {
  const sim::Scenario s = movingScenario(1, 40.0, 60.0);
  std::vector<Vec3> surveyed = s.p_w_anchors;
  std::swap(surveyed[0], surveyed[2]);
  InitializerParams p = paramsFor(s);
  p.heavy_nlos_after_s = 0.0;
  p.heavy_nlos_cost_factor = 100.0;

  InitializerParams any_share = p;
  any_share.max_short_range_share = 1.0;
  Initializer fooled(surveyed, any_share);
  EXPECT_TRUE(runInit(s, fooled).initialized) << fooled.status().message;

  Initializer init(surveyed, p);
  double least_short_share = 1.0;  // over the attempts refused for their cost
  const InitRun r = runInit(s, init, [&](const Initializer& in, const ImuSample&) {
    const auto [short_ranges, ranges] = alignmentShortRangesIn(in.status().message);
    if (ranges > 0) least_short_share = std::min(least_short_share, static_cast<double>(short_ranges) / ranges);
  });
  printRun("swapped", 1, r);
  EXPECT_FALSE(r.initialized) << r.status;
  EXPECT_GT(least_short_share, p.max_short_range_share) << r.status;
}

TEST(Initializer, StillStart40HzWaitsForMotionThenInitializes) {
  Tally t;
  for (std::uint64_t seed = 11; seed <= 16; ++seed) {
    const sim::Scenario s = stillStartScenario(seed, 40.0, 35.0, 4.0);
    Initializer init(s.p_w_anchors, paramsFor(s));
    bool saw_yaw_wait = false;
    const InitRun r = runInit(s, init, [&](const Initializer& in, const ImuSample& m) {
      if (m.t_ns < s.t0_ns + 4'000'000'000 && in.status().state == InitState::kYawUnobservable) {
        saw_yaw_wait = true;
        EXPECT_EQ(in.status().message.rfind("yaw not observable yet: moved 0.", 0), 0u)
            << in.status().message;
      }
      EXPECT_FALSE(m.t_ns < s.t0_ns + 4'000'000'000 && in.initialized()) << "initialized while still";
    });
    printRun("still 40 Hz", seed, r);
    EXPECT_TRUE(saw_yaw_wait);
    t.add(r, 0.3);
  }
  EXPECT_EQ(t.initialized, t.runs);
  EXPECT_GE(t.h, t.runs - 1) << "horizontal < 0.3 m";
  EXPECT_GE(t.pos, t.runs / 2) << "3D < 0.3 m";
  EXPECT_EQ(t.tilt, t.runs) << "roll/pitch < 2 deg";
  EXPECT_GE(t.yaw, t.runs - 1) << "yaw < 10 deg";
  EXPECT_GE(t.vel, t.runs - 1) << "velocity < 0.3 m/s";
}

TEST(Initializer, SparseRanging1HzUsesLongerWindows) {
  // One range per second: the window grows to hold enough ranges (up to
  // 45 s); the newest state's position is only known to ~0.5 m (one range a
  // second), attitude and velocity well.
  Tally t;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const sim::Scenario s = seed <= 4 ? movingScenario(seed, 1.0, 45.0) : stillStartScenario(seed, 1.0, 45.0, 4.0);
    Initializer init(s.p_w_anchors, paramsFor(s));
    const InitRun r = runInit(s, init);
    printRun(seed <= 4 ? "moving 1 Hz" : "still 1 Hz", seed, r);
    t.add(r, 1.0);
    if (r.initialized) {
      EXPECT_GT(init.result().window->graph.state_t_ns.back() - init.result().window_start_ns, 15'000'000'000);
    }
  }
  EXPECT_EQ(t.initialized, t.runs);
  EXPECT_GE(t.pos, t.runs - 1) << "3D < 1 m";
  EXPECT_EQ(t.tilt, t.runs) << "roll/pitch < 2 deg";
  EXPECT_GE(t.yaw, t.runs - 1) << "yaw < 10 deg";
  EXPECT_GE(t.vel, t.runs - 2) << "velocity < 0.3 m/s";
}

/// The moving walk with only anchors 0 and 1 heard for its first 14 s (no fix there).
constexpr std::int64_t kBlindNs = 14'000'000'000;
sim::Scenario blindStartScenario(std::uint64_t seed, double range_hz, double duration_s) {
  sim::Scenario s = movingScenario(seed, range_hz, duration_s);
  const std::int64_t t_blind_end = s.t0_ns + kBlindNs;
  std::erase_if(s.ranges, [&](const RangeSample& r) { return r.t_ns < t_blind_end && r.anchor_id > 1; });
  return s;
}

TEST(Initializer, AGrownWindowStartsAfterSecondsThatGaveNoFix) {
  // The smooth walk needs a window longer than window_s for yaw (the moving
  // starts above initialize at ~17 s). For the first 14 s only two anchors
  // are heard: no fix there. A grown window must start after those seconds
  // instead of staying pinned to the data's first sample, which deferred the
  // start until the 45 s window slid past them (office TDoA sim, seed 7:
  // 68.8 s of data).
  Tally t;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const sim::Scenario s = blindStartScenario(seed, 40.0, 50.0);
    Initializer init(s.p_w_anchors, paramsFor(s));
    const InitRun r = runInit(s, init);
    printRun("blind start", seed, r);
    t.add(r, 0.3);
    ASSERT_TRUE(r.initialized) << r.status;
    EXPECT_LT(r.time_s, 40.0);
    EXPECT_GE(init.result().window_start_ns, s.t0_ns + kBlindNs - 4'000'000'000);
  }
  EXPECT_GE(t.h, t.runs - 1) << "horizontal < 0.3 m";
  EXPECT_EQ(t.tilt, t.runs) << "roll/pitch < 2 deg";
  EXPECT_GE(t.yaw, t.runs - 1) << "yaw < 10 deg";
}

TEST(Initializer, AGrownWindowAfterSecondsWithoutAFixAtSparseRanging) {
  // As above at 4 ranges a second: a fix needs more than the 1 s fix window,
  // and the window's restart after the blind seconds must still find one
  // (capped at 1 s, seed 2 kept the 10 s window for good; before the restart
  // it waited until 55 s). Seed 3 starts 23 deg off in yaw, as it did before
  // the restart: a normal window holding two-anchor seconds, a known limit.
  int yaw_ok = 0;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const sim::Scenario s = blindStartScenario(seed, 4.0, 70.0);
    Initializer init(s.p_w_anchors, paramsFor(s));
    const InitRun r = runInit(s, init);
    printRun("blind 4 Hz", seed, r);
    ASSERT_TRUE(r.initialized) << r.status;
    EXPECT_LT(r.time_s, 40.0);
    yaw_ok += r.yaw_err_deg < 10.0;
  }
  EXPECT_GE(yaw_ok, 2) << "yaw < 10 deg";
}

// ---------------------------------------------------------------------------
// Garbage in: never a crash, never a wrong initialization, a reason.

struct Garbage {
  sim::Scenario s = movingScenario(21, 40.0, 12.0);
  Initializer init{s.p_w_anchors, paramsFor(s)};
  void feed(const std::vector<ImuSample>& imu, const std::vector<RangeSample>& ranges) {
    std::size_t i = 0, r = 0;
    while (i < imu.size() || r < ranges.size()) {
      if (r < ranges.size() && (i >= imu.size() || ranges[r].t_ns <= imu[i].t_ns)) {
        init.addRange(ranges[r++]);
      } else {
        init.addImu(imu[i++]);
        init.process();
      }
    }
  }
};

TEST(InitializerGarbage, ImuOnly) {
  Garbage g;
  g.feed(g.s.imu, {});
  EXPECT_FALSE(g.init.initialized());
  EXPECT_EQ(g.init.status().state, InitState::kWaitingForData);
  EXPECT_EQ(g.init.status().message, "waiting: no ranges (IMU only)");
  EXPECT_THROW(g.init.result(), std::logic_error);
}

TEST(InitializerGarbage, RangesOnlyAndNothing) {
  Garbage g;
  EXPECT_FALSE(g.init.process());
  EXPECT_EQ(g.init.status().message, "waiting: no samples");
  EXPECT_FALSE(g.init.attempt());
  g.feed({}, g.s.ranges);
  EXPECT_FALSE(g.init.process());
  EXPECT_EQ(g.init.status().message, "waiting: no IMU samples (ranges only)");
}

TEST(InitializerGarbage, OneAnchor) {
  Garbage g;
  std::vector<RangeSample> one;
  for (const RangeSample& r : g.s.ranges) {
    if (r.anchor_id == g.s.ranges.front().anchor_id) one.push_back(r);
  }
  g.feed(g.s.imu, one);
  EXPECT_FALSE(g.init.initialized());
  EXPECT_EQ(g.init.status().state, InitState::kTooFewAnchors);
  EXPECT_NE(g.init.status().message.find("1 anchors heard, need 4"), std::string::npos) << g.init.status().message;
}

TEST(InitializerGarbage, AbsurdButFiniteRanges) {
  Garbage g;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 40.0);
  std::vector<RangeSample> ranges = g.s.ranges;
  for (RangeSample& r : ranges) r.range_m = u(rng);
  g.feed(g.s.imu, ranges);
  EXPECT_FALSE(g.init.initialized()) << g.init.status().message;
  EXPECT_GT(g.init.status().attempts, 5);
  EXPECT_FALSE(g.init.status().message.empty());
}

TEST(InitializerGarbage, DeadAccelerometer) {
  Garbage g;
  std::vector<ImuSample> imu = g.s.imu;
  for (ImuSample& m : imu) m.accel_m_s2.setZero();
  g.feed(imu, g.s.ranges);
  EXPECT_FALSE(g.init.initialized());
  EXPECT_EQ(g.init.status().state, InitState::kNoGravity) << g.init.status().message;
}

TEST(InitializerGarbage, BadSamplesAreDroppedAndCounted) {
  Garbage g;
  ImuSample good = g.s.imu[0];
  g.init.addImu(good);
  g.init.addImu(good);  // same time
  ImuSample nan = g.s.imu[1];
  nan.gyro_rad_s.x() = std::nan("");
  g.init.addImu(nan);
  EXPECT_EQ(g.init.droppedImu(), 2u);
  RangeSample r = g.s.ranges[1];
  g.init.addRange(r);
  RangeSample earlier = g.s.ranges[0];
  g.init.addRange(earlier);  // before the previous range
  RangeSample unknown = r;
  unknown.anchor_id = 1000;
  g.init.addRange(unknown);
  RangeSample negative = r;
  negative.range_m = -1.0;
  g.init.addRange(negative);
  RangeSample huge = r;
  huge.range_m = 1e9;
  g.init.addRange(huge);
  RangeSample inf = r;
  inf.range_m = std::numeric_limits<double>::infinity();
  g.init.addRange(inf);
  EXPECT_EQ(g.init.droppedMeasurements(), 5u);
  EXPECT_EQ(g.init.measurementBuffer().size(), 1u);
  EXPECT_EQ(g.init.imuBuffer().size(), 1u);
}

TEST(InitializerGarbage, StillForeverNeverGuessesYaw) {
  const sim::Scenario s = stillStartScenario(22, 40.0, 15.0, 100.0);
  Initializer init(s.p_w_anchors, paramsFor(s));
  const InitRun r = runInit(s, init);
  EXPECT_FALSE(r.initialized);
  EXPECT_EQ(init.status().state, InitState::kYawUnobservable) << init.status().message;
  EXPECT_EQ(init.status().message.rfind("yaw not observable yet: moved 0.", 0), 0u) << init.status().message;
}

TEST(InitializerGarbage, BufferStaysBoundedWhileWaiting) {
  Garbage g;
  const std::vector<ImuSample> imu = stillImu(Mat3::Identity(), 120.0, 4, Vec3::Zero());
  g.feed(imu, {});
  // max_window_s + fix_max_window_s + 1 s kept, trimmed in chunks of 2 s.
  EXPECT_LE(g.init.imuBuffer().size(), static_cast<std::size_t>(800 * (45 + 8 + 1 + 2) + 1));
  EXPECT_GE(g.init.imuBuffer().size(), static_cast<std::size_t>(800 * (45 + 8 + 1)));
}

TEST(InitializerParamsTest, InvalidParamsAndAnchorsThrow) {
  const sim::Scenario s = movingScenario(1, 40.0, 1.0);
  InitializerParams p = paramsFor(s);
  p.min_window_s = 0.0;
  EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument);
  p = paramsFor(s);
  p.max_window_s = 5.0;  // < window_s
  EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument);
  p = paramsFor(s);
  p.height_band.max_height_m = 0.1;
  EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument);
  p = paramsFor(s);
  p.max_yaw_gap_noise_scale = 0.5;
  EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument);
  p = paramsFor(s);
  p.max_hand_over_residual_scale = std::numeric_limits<double>::infinity();
  EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument);
  for (double outside : {-1.0, std::nan("")}) {
    p = paramsFor(s);
    p.max_outside_anchors_m = outside;
    EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument) << outside;
  }
  for (double outside : {0.0, std::numeric_limits<double>::infinity()}) {
    p = paramsFor(s);
    p.max_outside_anchors_m = outside;
    EXPECT_NO_THROW(Initializer(s.p_w_anchors, p)) << outside;
  }
  const double inf = std::numeric_limits<double>::infinity();
  for (double after : {-1.0, std::nan("")}) {
    p = paramsFor(s);
    p.heavy_nlos_after_s = after;
    EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument) << after;
  }
  p = paramsFor(s);
  p.heavy_nlos_after_s = inf;  // off
  EXPECT_NO_THROW(Initializer(s.p_w_anchors, p));
  for (double share : {-0.1, 1.5}) {
    p = paramsFor(s);
    p.max_short_range_share = share;
    EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument) << share;
  }
  for (double factor : {0.5, inf}) {
    p = paramsFor(s);
    p.heavy_nlos_cost_factor = factor;
    EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument) << factor;
  }
  EXPECT_THROW(Initializer({}, paramsFor(s)), std::invalid_argument);
  EXPECT_THROW(Initializer({Vec3(0, 0, std::nan(""))}, paramsFor(s)), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Hand-over to the online estimator

TEST(InitializerHandOver, EstimatorTracksAfterReplay) {
  const sim::Scenario s = movingScenario(1, 40.0, 60.0);  // the default scenario (seed 1, 25 % NLOS)
  const InitializerParams p = paramsFor(s);
  Initializer init(s.p_w_anchors, p);
  // Feed until initialized; then feed 2 s more to the initializer, as a real
  // caller might before it switches over (nothing may be lost).
  std::size_t i = 0, r = 0;
  std::int64_t t_init = -1;
  auto next = [&](auto&& sink_range, auto&& sink_imu) {
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      sink_range(s.ranges[r++]);
    } else {
      sink_imu(s.imu[i++]);
    }
  };
  while (i < s.imu.size() && (t_init < 0 || s.imu[i].t_ns < t_init + 2'000'000'000)) {
    next([&](const RangeSample& x) { init.addRange(x); },
         [&](const ImuSample& m) {
           init.addImu(m);
           if (t_init < 0 && init.process()) t_init = m.t_ns;
         });
  }
  ASSERT_TRUE(init.initialized()) << init.status().message;

  SmootherParams sp;
  sp.lag_s = 5.0;
  RangeImuEstimator est(s.p_w_anchors, p.graph, std::make_unique<BayesTreeSmoother>(sp));
  const int replayed_updates = handOver(init, est);
  EXPECT_GT(replayed_updates, 70);  // ~2 s of 40 Hz states
  EXPECT_EQ(est.stream().droppedRanges(), 0u);
  EXPECT_THROW(handOver(init, est), std::logic_error);  // already started

  // Then the live data goes to the estimator.
  const std::int64_t t_state = init.result().state.t_ns;
  double sum_3d = 0.0, sum_h = 0.0, max_h = 0.0;
  int n = 0;
  while (i < s.imu.size() || r < s.ranges.size()) {
    next([&](const RangeSample& x) { est.addRange(x); }, [&](const ImuSample& m) { est.addImu(m); });
    if (est.process() > 0 && est.latest().t_ns <= t_state + 20'000'000'000) {
      const Vec3 d = est.latest().T_w_b.p - s.truthAt(est.latest().t_ns).T_w_b.p;
      sum_3d += d.norm();
      sum_h += d.head<2>().norm();
      max_h = std::max(max_h, d.head<2>().norm());
      ++n;
    }
  }
  ASSERT_GT(n, 600);
  std::printf("hand-over: initialized at %.1f s, next 20 s: mean 3D %.3f m, mean horizontal %.3f m, max horizontal %.3f m\n",
              init.result().time_to_init_s, sum_3d / n, sum_h / n, max_h);
  EXPECT_LT(sum_3d / n, 0.5);
  EXPECT_LT(sum_h / n, 0.3);
  EXPECT_LT(max_h, 1.0);
}

// InitializerParams::hand_over_later_measurements: under sparse ranging the
// state handed over is the newest one that at least that many of the
// window's measurements follow, with its own marginals; 0 hands over the
// newest. At 1 Hz ranging the newest state has the fewest measurements on
// its side: over 4 seeds the hand-over state must be no worse than the
// newest one on average. (Dense ranging: Initializer.MovingStart40Hz...)
TEST(InitializerHandOver, HandsOverTheNewestStateThatEnoughMeasurementsFollow) {
  double sum_handed = 0.0, sum_newest = 0.0;
  int runs = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const sim::Scenario s = movingScenario(seed, 1.0, 60.0);
    InitializerParams p = paramsFor(s);
    ASSERT_EQ(p.hand_over_later_measurements, 20);
    Initializer init(s.p_w_anchors, p);
    const InitRun r = runInit(s, init);
    if (!r.initialized) continue;
    const InitResult& res = init.result();
    ASSERT_TRUE(res.window.has_value());
    const std::vector<std::int64_t>& ts = res.window->graph.state_t_ns;
    ASSERT_LT(res.state.index, ts.size() - 1) << "not the newest state";
    EXPECT_EQ(res.state.t_ns, ts[res.state.index]);
    EXPECT_TRUE(res.state.T_w_b.p.isApprox(res.window->values.pose(sym::X(res.state.index)).p));
    // Measurements of the window after it: at least 20, and fewer after the next state.
    auto later = [&](std::int64_t t_ns) {
      return std::count_if(init.measurementBuffer().begin(), init.measurementBuffer().end(), [&](const Measurement& m) {
        return m.t_ns > t_ns && m.t_ns <= ts.back();
      });
    };
    EXPECT_GE(later(res.state.t_ns), 20);
    EXPECT_LT(later(ts[res.state.index + 1]), 20);
    ASSERT_TRUE(res.start_covariance.has_value());
    const Vec3 p_newest = res.window->values.pose(sym::X(ts.size() - 1)).p;
    sum_handed += (res.state.T_w_b.p - s.truthAt(res.state.t_ns).T_w_b.p).norm();
    sum_newest += (p_newest - s.truthAt(ts.back()).T_w_b.p).norm();
    ++runs;

    // 0: the newest state, as before.
    p.hand_over_later_measurements = 0;
    Initializer newest(s.p_w_anchors, p);
    ASSERT_TRUE(runInit(s, newest).initialized);
    EXPECT_EQ(newest.result().state.index, newest.result().window->graph.state_t_ns.size() - 1);
  }
  ASSERT_GE(runs, 3);
  std::printf("1 Hz hand-over: mean position error %.3f m at the hand-over state, %.3f m at the newest (%d runs)\n",
              sum_handed / runs, sum_newest / runs, runs);
  EXPECT_LE(sum_handed, sum_newest);
  InitializerParams bad;
  bad.hand_over_later_measurements = -1;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  bad.hand_over_later_measurements = 20;
  bad.hand_over_sparse_span_s = -1.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(InitializerHandOver, RefusesWhenNotInitialized) {
  const sim::Scenario s = movingScenario(1, 40.0, 1.0);
  Initializer init(s.p_w_anchors, paramsFor(s));
  RangeImuEstimator est(s.p_w_anchors, paramsFor(s).graph, std::make_unique<BayesTreeSmoother>(SmootherParams()));
  EXPECT_THROW(handOver(init, est), std::logic_error);
  EXPECT_FALSE(est.stream().started());
}

// ---------------------------------------------------------------------------
// Survey (not run by default: --gtest_also_run_disabled_tests): the
// per-seed figures quoted in the report.

TEST(DISABLED_InitializerSurvey, PrintsErrorsAndTimeToInitializePerSeed) {
  struct Case {
    const char* name;
    double rate_hz;
    bool still;
  };
  for (const Case& c : {Case{"moving 40 Hz", 40.0, false}, Case{"still 40 Hz", 40.0, true},
                        Case{"moving 1 Hz", 1.0, false}, Case{"still 1 Hz", 1.0, true}}) {
    Tally t;
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
      const double duration = c.rate_hz < 5.0 ? 50.0 : 40.0;
      const sim::Scenario s =
          c.still ? stillStartScenario(seed, c.rate_hz, duration, 4.0) : movingScenario(seed, c.rate_hz, duration);
      Initializer init(s.p_w_anchors, paramsFor(s));
      const InitRun r = runInit(s, init);
      printRun(c.name, seed, r);
      std::printf("    %d attempts, %d batch solves\n", init.status().attempts, init.status().batch_solves);
      t.add(r, c.rate_hz < 5.0 ? 1.0 : 0.3);
    }
    std::printf("%s: %d/%d initialized; pos < %.1f m %d, horizontal %d, tilt < 2 deg %d, yaw < 10 deg %d, vel < 0.3 m/s %d\n\n",
                c.name, t.initialized, t.runs, c.rate_hz < 5.0 ? 1.0 : 0.3, t.pos, t.h, t.tilt, t.yaw, t.vel);
  }
}

}  // namespace
}  // namespace rilo
