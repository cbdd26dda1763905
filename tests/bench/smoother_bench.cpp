// Per-update cost of the incremental smoothers on the Ranging-IMU Fusion paper's setting: a
// simulated office walk, 8 anchors (4 ranged per cycle), 40 Hz ranging,
// 800 Hz IMU, states predicted by the IMU from the smoother's own estimate.
// Reported per configuration: mean / p99 / max update time (ms), the online
// error of the newest state against the truth (m), work per update.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <fstream>
#include <memory>
#include <numeric>

#include "estimation/smoother/bayes_tree_smoother.h"
#include "sim/range_imu_scenario.h"
#include "support/online_run.h"

namespace rilo {
namespace {

const sim::Scenario& walk(double seconds) {
  static std::unique_ptr<sim::Scenario> cached;
  static double cached_seconds = 0.0;
  if (!cached || cached_seconds != seconds) {
    sim::ScenarioParams sp;
    sp.duration_s = seconds;
    cached = std::make_unique<sim::Scenario>(sim::simulateScenario(sp));
    cached_seconds = seconds;
  }
  return *cached;
}

double residentMegabytes() {
  std::ifstream statm("/proc/self/statm");
  long pages_total = 0, pages_resident = 0;
  statm >> pages_total >> pages_resident;
  return static_cast<double>(pages_resident) * 4096.0 / 1e6;
}

struct RunFigures {
  std::vector<double> update_ms;
  double online_error_sum_m = 0.0;
  long online_error_count = 0;
  long cliques = 0, relinearized = 0, tries = 0, rejected = 0;
};

RunFigures runWalk(const sim::Scenario& s, SmootherParams params, bool anchors_as_variables, const char* loss,
                   std::int64_t state_window_ns = RangeImuGraphParams().same_state_window_ns) {
  RunFigures fig;
  auto smoother = std::make_unique<BayesTreeSmoother>(params);
  RangeImuGraphParams graph = testing::graphParamsFor(s, loss, anchors_as_variables);
  graph.same_state_window_ns = state_window_ns;
  RangeImuEstimator estimator(s.p_w_anchors, graph, std::move(smoother));
  testing::runOnline(s, estimator, [&](const UpdateStats& st, const RangeImuEstimator& e) {
    fig.update_ms.push_back(st.time_s * 1e3);
    fig.cliques += st.cliques_reeliminated;
    fig.relinearized += st.variables_relinearized;
    fig.tries += st.step_tries;
    fig.rejected += st.step_accepted ? 0 : 1;
    fig.online_error_sum_m += (e.latest().T_w_b.p - s.truthAt(e.latest().t_ns).T_w_b.p).norm();
    ++fig.online_error_count;
  });
  return fig;
}

void report(benchmark::State& state, RunFigures& fig) {
  std::vector<double>& t = fig.update_ms;
  std::sort(t.begin(), t.end());
  const double n = static_cast<double>(t.size());
  state.counters["updates"] = n;
  state.counters["mean_ms"] = std::accumulate(t.begin(), t.end(), 0.0) / n;
  state.counters["p99_ms"] = t[static_cast<std::size_t>(0.99 * (n - 1))];
  state.counters["max_ms"] = t.back();
  state.counters["online_err_m"] = fig.online_error_sum_m / static_cast<double>(fig.online_error_count);
  state.counters["cliques_per_upd"] = static_cast<double>(fig.cliques) / n;
  state.counters["relin_per_upd"] = static_cast<double>(fig.relinearized) / n;
  state.counters["tries_per_upd"] = static_cast<double>(fig.tries) / n;
  state.counters["rejected"] = static_cast<double>(fig.rejected);
}

/// Args: method (0 iSAM2, 1 D-iSAM2, 2 dog-leg), anchors as variables (0/1),
/// lag (s, 0 = none), state window (ms: ranges this close share a state;
/// 50 is the service's, 5 one state per 40 Hz range).
void BM_SmootherWalk60s(benchmark::State& state) {
  const sim::Scenario& s = walk(60.0);
  SmootherParams params;
  params.method = static_cast<SmootherParams::Method>(state.range(0));
  params.lag_s = static_cast<double>(state.range(2));
  for (auto _ : state) {
    RunFigures fig = runWalk(s, params, state.range(1) != 0, "asymmetric", state.range(3) * 1'000'000);
    report(state, fig);
  }
}
BENCHMARK(BM_SmootherWalk60s)
    ->ArgNames({"method", "anchor_vars", "lag_s", "window_ms"})
    ->Args({1, 1, 5, 5})
    ->Args({0, 1, 5, 5})
    ->Args({2, 1, 5, 5})
    ->Args({1, 0, 5, 5})
    ->Args({1, 1, 0, 5})
    ->Args({1, 1, 10, 5})
    ->Args({1, 1, 10, 50})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

/// One hour of operation (D-iSAM2, anchors as variables, 5 s lag): update
/// time per 10-minute block and resident memory, to show both stay flat.
void BM_SmootherHour(benchmark::State& state) {
  const sim::Scenario& s = walk(3600.0);
  SmootherParams params;
  params.lag_s = 5.0;
  for (auto _ : state) {
    auto smoother = std::make_unique<BayesTreeSmoother>(params);
    BayesTreeSmoother* raw = smoother.get();
    RangeImuEstimator estimator(s.p_w_anchors, testing::graphParamsFor(s), std::move(smoother));
    std::vector<double> block_ms;
    double rss_after_1min = 0.0;
    std::size_t slots_after_1min = 0;
    std::int64_t block_start = s.ranges.front().t_ns;
    std::int64_t t_first = block_start;
    double sum_ms = 0.0, max_ms = 0.0;
    long n = 0;
    testing::runOnline(s, estimator, [&](const UpdateStats& st, const RangeImuEstimator& e) {
      sum_ms += st.time_s * 1e3;
      max_ms = std::max(max_ms, st.time_s * 1e3);
      ++n;
      if (rss_after_1min == 0.0 && e.latest().t_ns - t_first > 60'000'000'000) {
        rss_after_1min = residentMegabytes();
        slots_after_1min = raw->slotCapacity();
      }
      if (e.latest().t_ns - block_start >= 600'000'000'000) {
        block_ms.push_back(sum_ms / static_cast<double>(n));
        sum_ms = 0.0;
        n = 0;
        block_start = e.latest().t_ns;
      }
    });
    for (std::size_t b = 0; b < block_ms.size(); ++b) {
      state.counters["mean_ms_block" + std::to_string(b)] = block_ms[b];
    }
    state.counters["max_ms"] = max_ms;
    state.counters["rss_mb_1min"] = rss_after_1min;
    state.counters["rss_mb_end"] = residentMegabytes();
    state.counters["slots_1min"] = static_cast<double>(slots_after_1min);
    state.counters["slots_end"] = static_cast<double>(raw->slotCapacity());
    state.counters["cliques_end"] = raw->cliqueCount();
  }
}
BENCHMARK(BM_SmootherHour)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace
}  // namespace rilo
