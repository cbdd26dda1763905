#include "demo.h"

#include <chrono>
#include <cstdio>
#include <random>

#include "estimation/pipeline/range_imu_graph.h"
#include "estimation/pipeline/trajectory_error.h"
#include "estimation/solver/batch_lm.h"
#include "hal/sim/range_imu_scenario.h"

namespace rilo::tool {
namespace {

/// Ground truth perturbed by Gaussian noise: the batch solve's starting point
/// (initialization from scratch comes with the pipeline).
Values perturbedTruth(const sim::Scenario& s, const RangeImuGraph& g, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  auto randn3 = [&] { return Vec3(n01(rng), n01(rng), n01(rng)); };
  Values v;
  for (std::size_t i = 0; i < g.state_t_ns.size(); ++i) {
    const sim::KinematicState st = s.truthAt(g.state_t_ns[i]);
    Vec6 xi;
    xi << 0.05 * randn3(), 0.3 * randn3();
    v.insert(sym::X(i), st.T_w_b.retract(xi));
    v.insert(sym::V(i), Vec3(st.v_w + 0.2 * randn3()));
    v.insert(sym::B(i), ImuBias());
  }
  for (Key l : g.anchor_keys) v.insert(l, s.p_w_anchors.at(keyIndex(l)));
  return v;
}

std::vector<Vec3> positions(const Values& v, std::size_t n) {
  std::vector<Vec3> p;
  p.reserve(n);
  for (std::size_t i = 0; i < n; ++i) p.push_back(v.pose(sym::X(i)).p);
  return p;
}

}  // namespace

int runDemo(const DemoOptions& o) {
  sim::ScenarioParams sp;
  sp.seed = o.seed;
  sp.duration_s = o.seconds;
  sp.range_rate_hz = o.range_hz;
  sp.nlos_fraction = o.nlos_fraction;
  const sim::Scenario s = sim::simulateScenario(sp);
  std::size_t nlos = 0;
  for (const auto& r : s.ranges) nlos += r.los == 0 ? 1 : 0;
  std::printf("rilo demo: %.0f s walk, %zu anchors, %zu IMU samples (%.0f Hz), %zu ranges (%.0f Hz, %.0f%% NLOS), seed %llu\n",
              sp.duration_s, s.p_w_anchors.size(), s.imu.size(), sp.imu_rate_hz, s.ranges.size(), sp.range_rate_hz,
              100.0 * static_cast<double>(nlos) / static_cast<double>(s.ranges.size()),
              static_cast<unsigned long long>(sp.seed));
  std::printf("start: ground truth perturbed by 0.3 m / 0.05 rad / 0.2 m/s per state; solver: batch Levenberg-Marquardt (CHOLMOD)\n\n");
  std::printf("%-12s %8s %8s %8s %8s %8s %6s %9s %s\n", "noise model", "APE mean", "median", "max", "horiz", "vert",
              "iters", "time [s]", "status");

  RangeImuGraphParams gp;
  gp.p_b_tag = s.p_b_tag;
  gp.imu.gyro_noise_density = sp.gyro_noise_density;
  gp.imu.accel_noise_density = sp.accel_noise_density;
  gp.imu.gyro_bias_random_walk = sp.gyro_bias_walk;
  gp.imu.accel_bias_random_walk = sp.accel_bias_walk;
  gp.range_noise.sigma_m = sp.range_sigma_m;

  const sim::KinematicState st0 = s.truthAt(s.ranges.front().t_ns);
  std::vector<Vec3> p_true;
  int rc = 0;
  for (const std::string& model : o.noise_models) {
    gp.range_loss = model;
    const RangeImuGraph g = buildRangeImuGraph(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp);
    if (p_true.empty()) {
      for (std::int64_t t : g.state_t_ns) p_true.push_back(s.truthAt(t).T_w_b.p);
    }
    const Values initial = perturbedTruth(s, g, o.seed + 1000);
    BatchLevenbergMarquardt lm;
    const auto t_start = std::chrono::steady_clock::now();
    const auto out = lm.optimize(g.graph, initial);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    const PositionErrorStats e = positionErrorStats(positions(out.values, g.state_t_ns.size()), p_true);
    std::printf("%-12s %8.3f %8.3f %8.3f %8.3f %8.3f %6d %9.2f %s\n", model.c_str(), e.ape_3d.mean, e.ape_3d.median,
                e.ape_3d.max, e.ape_horizontal.mean, e.ape_vertical.mean, out.result.iterations, secs,
                out.result.message.c_str());
    // Not converging within the budget is a result worth showing; numerical failure is an error.
    if (out.result.status == LmStatus::kNonFiniteError || out.result.status == LmStatus::kLinearSolverFailure) rc = 1;
  }
  std::printf("\nAPE in metres over %zu states (no alignment: anchors fix the frame).\n", p_true.size());
  return rc;
}

}  // namespace rilo::tool
