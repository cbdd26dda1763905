#include "demo.h"

#include <chrono>
#include <cstdio>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/solver/batch_lm.h"
#include "evaluation/trajectory_error.h"
#include "sim/range_imu_scenario.h"

namespace rilo::tool {
namespace {

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
  gp.imu = sim::imuParamsOf(sp);
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
    sim::TruthPerturbation perturbation;
    perturbation.seed = o.seed + 1000;
    const Values initial = sim::truthValues(s, g.state_t_ns, g.anchor_keys, &perturbation);
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
