// Batch LM on a window like the Initializer's: 10 s and 20 s of 40 Hz ranging
// with the IMU (15 variables per state, 8 anchor variables), the
// Initializer's LM settings, started from a perturbed ground truth. Besides
// whole solves, the parts of one LM iteration: linearization into the normal
// equations, the numeric factorization, the nonlinear error, and the
// marginal covariance of the newest pose the Initializer asks for; the
// Initializer's gate probe (that marginal at the starting values), the probe
// followed by the solve with and without sharing the solver
// (BatchLevenbergMarquardt::covarianceAt), and its range-inertial yaw
// alignment, which every attempt runs.
//
// Measured (process CPU time, shared 2-core machine under load ~4-7, so a few
// percent of noise): BM_InitAlignment 10 s / 20 s 22.5 / 46 ms before the
// alignment's evaluation reuse, lower-triangle sums, series sin/cos and early
// cost exit, 16.0 / 32.3 ms after; BM_InitWindowGateThenSolve 10 s
// 38.5 ms (separate probe solver) -> 34.7 ms (shared, covarianceAt), 20 s
// 128 -> 121 ms.
#include <benchmark/benchmark.h>

#include <string>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/init/alignment.h"
#include "estimation/init/gravity.h"
#include "estimation/init/initializer.h"
#include "estimation/solver/batch_lm.h"
#include "estimation/solver/normal_equations.h"
#include "estimation/solver/ordering.h"
#include "sim/range_imu_scenario.h"

namespace rilo {
namespace {

struct WindowProblem {
  RangeImuGraph graph;
  Values initial;
};

WindowProblem makeWindow(double seconds) {
  sim::ScenarioParams sp;
  sp.duration_s = seconds;
  const sim::Scenario s = sim::simulateScenario(sp);
  RangeImuGraphParams gp;
  gp.imu = sim::imuParamsOf(sp);
  gp.p_b_tag = s.p_b_tag;
  gp.range_loss = "asymmetric";
  gp.range_noise.sigma_m = sp.range_sigma_m;
  const sim::KinematicState st0 = s.truthAt(s.ranges.front().t_ns);
  WindowProblem wp{buildRangeImuGraph(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp), {}};
  sim::TruthPerturbation perturbation;
  perturbation.seed = 5;
  wp.initial = sim::truthValues(s, wp.graph.state_t_ns, wp.graph.anchor_keys, &perturbation);
  return wp;
}

void setCounters(benchmark::State& state, const WindowProblem& wp, const LmResult& r) {
  state.counters["states"] = static_cast<double>(wp.graph.state_t_ns.size());
  state.counters["lm_iterations"] = r.iterations;
  state.counters["factorizations"] = r.factorizations;
  state.counters["ms_per_factorization"] = r.factorizations > 0 ? 1e3 * r.time_s / r.factorizations : 0.0;
}

/// A whole solve plus the newest pose's marginal, as Initializer::solveBatch does.
void BM_InitWindowSolve(benchmark::State& state) {
  const WindowProblem wp = makeWindow(static_cast<double>(state.range(0)));
  const Key x_last = sym::X(wp.graph.state_t_ns.size() - 1);
  LmResult last;
  for (auto _ : state) {
    BatchLevenbergMarquardt lm(InitializerParams::defaultLmParams());
    const auto out = lm.optimize(wp.graph.graph, wp.initial);
    benchmark::DoNotOptimize(lm.marginalCovariance(x_last));
    last = out.result;
  }
  setCounters(state, wp, last);
}
BENCHMARK(BM_InitWindowSolve)->Arg(10)->Arg(20)->Arg(45)->Unit(benchmark::kMillisecond)->MinTime(2.0);

/// Linearizing every factor into H and g (the per-iteration assembly).
void BM_InitWindowLinearize(benchmark::State& state) {
  const WindowProblem wp = makeWindow(static_cast<double>(state.range(0)));
  NormalEquations ne;
  ne.setStructure(wp.graph.graph, wp.initial, colamdOrdering(wp.graph.graph));
  for (auto _ : state) {
    ne.linearize(wp.graph.graph, wp.initial);
    benchmark::DoNotOptimize(ne.gradient().data());
  }
  state.counters["dim"] = ne.dim();
  state.counters["nnz_H"] = ne.nonzeros();
}
BENCHMARK(BM_InitWindowLinearize)->Arg(10)->Arg(20)->Unit(benchmark::kMicrosecond);

/// One numeric factorization of the (damped) Hessian. Second argument: the
/// kernel (0 CHOLMOD on the system BLAS, 1 SupernodalCholesky on Eigen).
void BM_InitWindowFactorize(benchmark::State& state) {
  const WindowProblem wp = makeWindow(static_cast<double>(state.range(0)));
  NormalEquations ne;
  ne.setStructure(wp.graph.graph, wp.initial, colamdOrdering(wp.graph.graph));
  ne.linearize(wp.graph.graph, wp.initial);
  CholmodContext ctx;
  CholmodFactor factor;
  const AnalyzeOptions options{.postorder = false,
                               .kernel = state.range(1) != 0 ? AnalyzeOptions::Kernel::kSupernodalEigen
                                                             : AnalyzeOptions::Kernel::kCholmod};
  if (!ctx.analyze(ne.hessian(), {}, options, &factor).ok()) {
    state.SkipWithError("analyze failed");
    return;
  }
  for (auto _ : state) {
    const CholmodResult r = ctx.factorize(ne.hessian(), FactorizeOptions{.shift = 1e-4}, factor);
    if (!r.ok()) state.SkipWithError(r.message.c_str());
  }
  state.counters["dim"] = ne.dim();
  state.counters["nnz_L"] = factor.factorNonzeros();
  state.counters["supernodal"] = factor.isSupernodal() ? 1.0 : 0.0;
}
BENCHMARK(BM_InitWindowFactorize)
    ->ArgNames({"window_s", "eigen"})
    ->Args({10, 0})
    ->Args({10, 1})
    ->Args({20, 0})
    ->Args({20, 1})
    ->Unit(benchmark::kMicrosecond);

/// The nonlinear error of a candidate step (robust losses of every factor).
void BM_InitWindowError(benchmark::State& state) {
  const WindowProblem wp = makeWindow(static_cast<double>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(wp.graph.graph.error(wp.initial));
}
BENCHMARK(BM_InitWindowError)->Arg(10)->Arg(20)->Unit(benchmark::kMicrosecond);

/// The Initializer's batch gate: the newest pose's marginal at the starting
/// values (no LM iteration: structure, one linearization, one factorization),
/// to compare with BM_InitWindowSolve.
void BM_InitWindowGateProbe(benchmark::State& state) {
  const WindowProblem wp = makeWindow(static_cast<double>(state.range(0)));
  const Key x_last = sym::X(wp.graph.state_t_ns.size() - 1);
  LmParams probe_params = InitializerParams::defaultLmParams();
  probe_params.max_iterations = 0;
  for (auto _ : state) {
    BatchLevenbergMarquardt probe(probe_params);
    benchmark::DoNotOptimize(probe.optimize(wp.graph.graph, wp.initial).result.initial_error);
    benchmark::DoNotOptimize(probe.marginalCovariance(x_last));
  }
  state.counters["states"] = static_cast<double>(wp.graph.state_t_ns.size());
}
BENCHMARK(BM_InitWindowGateProbe)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond)->MinTime(2.0);

/// The gate probe followed by the solve and the newest pose's marginal, as
/// Initializer::solveBatch runs them when the gate lets the solve through.
/// Second argument 0: a separate zero-iteration probe solver and a fresh
/// solver for the solve (before covarianceAt); 1: one solver,
/// covarianceAt() then optimize(), which reuses the probe's ordering,
/// symbolic analysis and first linearization.
void BM_InitWindowGateThenSolve(benchmark::State& state) {
  const WindowProblem wp = makeWindow(static_cast<double>(state.range(0)));
  const Key x_last = sym::X(wp.graph.state_t_ns.size() - 1);
  const bool shared = state.range(1) != 0;
  LmParams probe_params = InitializerParams::defaultLmParams();
  probe_params.max_iterations = 0;
  LmResult last;
  for (auto _ : state) {
    BatchLevenbergMarquardt lm(InitializerParams::defaultLmParams());
    if (shared) {
      benchmark::DoNotOptimize(lm.covarianceAt(wp.graph.graph, wp.initial, x_last));
    } else {
      BatchLevenbergMarquardt probe(probe_params);
      benchmark::DoNotOptimize(probe.optimize(wp.graph.graph, wp.initial).result.initial_error);
      benchmark::DoNotOptimize(probe.marginalCovariance(x_last));
    }
    const auto out = lm.optimize(wp.graph.graph, wp.initial);
    benchmark::DoNotOptimize(lm.marginalCovariance(x_last));
    last = out.result;
  }
  setCounters(state, wp, last);
}
BENCHMARK(BM_InitWindowGateThenSolve)
    ->ArgNames({"window_s", "shared"})
    ->Args({10, 0})
    ->Args({10, 1})
    ->Args({20, 0})
    ->Args({20, 1})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(2.0);

/// The range-inertial yaw alignment every attempt runs (8 yaw hypotheses, 15
/// unknowns, every measurement of the window) from the window start.
void BM_InitAlignment(benchmark::State& state) {
  sim::ScenarioParams sp;
  sp.duration_s = static_cast<double>(state.range(0));
  const sim::Scenario s = sim::simulateScenario(sp);
  const std::int64_t t0 = s.ranges.front().t_ns;
  GravityParams gp;
  const GravityAlignment gravity = alignGravity(s.imu, t0, s.imu.back().t_ns, 9.81, gp);
  AlignmentParams ap;
  ap.range_sigma_m = sp.range_sigma_m;
  ap.p_b_tag = s.p_b_tag;
  ap.band.enabled = false;
  const sim::KinematicState st0 = s.truthAt(t0);
  const Vec3 p_tag0 = st0.T_w_b.transformFrom(s.p_b_tag) + Vec3(0.2, -0.1, 0.1);  // a fix's error
  std::vector<Measurement> meas;
  for (const RangeSample& r : s.ranges) meas.push_back(Measurement::of(r));
  AlignmentResult last;
  for (auto _ : state) {
    last = alignRangeInertial(s.imu, meas, t0, s.p_w_anchors, gravity, p_tag0, st0.v_w, ap);
    benchmark::DoNotOptimize(last.cost);
  }
  state.counters["measurements"] = last.measurements;
  state.counters["yaw_sigma_deg"] = last.yaw_sigma_rad * 180.0 / M_PI;
}
BENCHMARK(BM_InitAlignment)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
}  // namespace rilo
