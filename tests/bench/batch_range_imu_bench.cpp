// Batch LM on the Ranging-IMU Fusion paper's range + IMU graph: a 60 s walk at 40 Hz ranging
// (about 2300 states, 15 variables each, 8 anchor variables) solved from a
// perturbed ground truth, per noise model.
#include <benchmark/benchmark.h>


#include "estimation/assembly/range_imu_graph.h"
#include "estimation/solver/batch_lm.h"
#include "sim/range_imu_scenario.h"

namespace rilo {
namespace {

struct BenchProblem {
  RangeImuGraph graph;
  Values initial;
};

BenchProblem makeBenchProblem(const std::string& loss, double seconds) {
  sim::ScenarioParams sp;
  sp.duration_s = seconds;
  const sim::Scenario s = sim::simulateScenario(sp);
  RangeImuGraphParams gp;
  gp.p_b_tag = s.p_b_tag;
  gp.range_loss = loss;
  gp.range_noise.sigma_m = sp.range_sigma_m;
  const sim::KinematicState st0 = s.truthAt(s.ranges.front().t_ns);
  BenchProblem bp{buildRangeImuGraph(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp), {}};
  sim::TruthPerturbation perturbation;
  perturbation.seed = 5;
  bp.initial = sim::truthValues(s, bp.graph.state_t_ns, bp.graph.anchor_keys, &perturbation);
  return bp;
}

void BM_BatchLm60s40Hz(benchmark::State& state, const char* loss) {
  const BenchProblem bp = makeBenchProblem(loss, 60.0);
  int iterations = 0;
  for (auto _ : state) {
    BatchLevenbergMarquardt lm;
    const auto out = lm.optimize(bp.graph.graph, bp.initial);
    iterations = out.result.iterations;
    benchmark::DoNotOptimize(out.result.final_error);
  }
  state.counters["states"] = static_cast<double>(bp.graph.state_t_ns.size());
  state.counters["lm_iterations"] = iterations;
}
BENCHMARK_CAPTURE(BM_BatchLm60s40Hz, gaussian, "gaussian")->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK_CAPTURE(BM_BatchLm60s40Hz, asymmetric, "asymmetric")->Unit(benchmark::kMillisecond)->Iterations(2);

/// One linearization + factorization of the 60 s problem: the per-iteration cost.
void BM_BatchLmSingleIteration60s(benchmark::State& state) {
  const BenchProblem bp = makeBenchProblem("asymmetric", 60.0);
  LmParams p;
  p.max_iterations = 1;
  for (auto _ : state) {
    BatchLevenbergMarquardt lm(p);
    benchmark::DoNotOptimize(lm.optimize(bp.graph.graph, bp.initial).result.final_error);
  }
}
BENCHMARK(BM_BatchLmSingleIteration60s)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
}  // namespace rilo
