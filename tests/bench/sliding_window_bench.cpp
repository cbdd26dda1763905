// Per-update cost of SlidingWindowSmoother on the Ranging-IMU Fusion paper's range + IMU setting,
// driven online through RangeImuEstimator: a simulated office walk, 8
// anchors as variables with survey priors, 800 Hz IMU, one state every 25 ms
// carrying 4 ranges (160 ranges/s in cycles of 4, grouped by a 20 ms
// same-state window). A 10 s window then holds 400 states x 15 dof.
// Reported after the window has filled: mean / p50 / p99 / max update time
// (ms, wall and process CPU), LM iterations per update, window size, online
// error of the newest state against the truth (m; this NLOS-heavy 160 Hz
// scenario costs both smoothers 0.1-0.9 m depending on its length).
//
// Measured on the shared 2-core machine (load average 6-7, so wall times
// are about twice the CPU times), process CPU per update, mean / p99 / max:
//   window 2 s (80 states)   2.5 /  9.0 / 11 ms
//   window 5 s (200 states)  6.1 /  9.0 / 22 ms
//   window 10 s (395 states) 12.1 / 21.5 / 39 ms (FEJ 13.3 mean; at most 2
//                            LM iterations: 12.2 / 21.9 / 23 ms)
//   fixed-lag D-iSAM2 on the same walk: 0.7 (2 s) and 1.2 (10 s) ms mean.
// About half of it is CHOLMOD's supernodal factorization on the reference
// BLAS (the only BLAS installed).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <ctime>
#include <functional>
#include <memory>
#include <numeric>

#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/smoother/sliding_window_smoother.h"
#include "sim/range_imu_scenario.h"
#include "support/online_run.h"

namespace rilo {
namespace {

const sim::Scenario& fourRangesPerState(double seconds) {
  static std::unique_ptr<sim::Scenario> cached;
  static double cached_seconds = 0.0;
  if (!cached || cached_seconds != seconds) {
    sim::ScenarioParams sp;
    sp.duration_s = seconds;
    sp.range_rate_hz = 160.0;
    sp.ranges_per_cycle = 4;
    cached = std::make_unique<sim::Scenario>(sim::simulateScenario(sp));
    cached_seconds = seconds;
  }
  return *cached;
}

/// Forwards to a smoother and records the process CPU time of each update
/// (all threads: CHOLMOD may use OpenMP): on a machine shared with other
/// jobs the wall time of UpdateStats::time_s includes waiting for a core.
class CpuTimed final : public Smoother {
 public:
  explicit CpuTimed(std::unique_ptr<Smoother> inner) : inner_(std::move(inner)) {}
  UpdateStats update(const FactorGraph& f, const Values& v, const KeyTimestamps& t) override {
    const double t0 = cpuSeconds();
    const UpdateStats st = inner_->update(f, v, t);
    last_cpu_s = cpuSeconds() - t0;
    return st;
  }
  Values estimate() const override { return inner_->estimate(); }
  Variable estimate(Key key) const override { return inner_->estimate(key); }
  bool exists(Key key) const override { return inner_->exists(key); }
  std::optional<CovarianceBlock> marginalCovariance(Key key, std::string* failure) override {
    return inner_->marginalCovariance(key, failure);
  }
  double error() const override { return inner_->error(); }
  void drainMarginalized(std::vector<std::pair<Key, Variable>>& out) override { inner_->drainMarginalized(out); }

  double last_cpu_s = 0.0;

 private:
  static double cpuSeconds() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  }
  std::unique_ptr<Smoother> inner_;
};

/// Runs the walk online with `smoother` and reports after the window has
/// filled: wall time per update (UpdateStats::time_s) and process CPU time.
void runAndReport(benchmark::State& state, const sim::Scenario& s, double window_s,
                  const std::function<std::unique_ptr<Smoother>()>& make) {
  RangeImuGraphParams gp = testing::graphParamsFor(s);
  gp.same_state_window_ns = 20'000'000;  // the 4 ranges of a 25 ms cycle share one state
  for (auto _ : state) {
    std::vector<double> update_ms, cpu_ms;
    double error_sum_m = 0.0;
    long tries = 0, ranges = 0;
    int most_states = 0;
    const std::int64_t steady_from = s.ranges.front().t_ns + static_cast<std::int64_t>((window_s + 1.0) * 1e9);
    auto timed = std::make_unique<CpuTimed>(make());
    CpuTimed* cpu = timed.get();
    RangeImuEstimator estimator(s.p_w_anchors, gp, std::move(timed));
    testing::runOnline(s, estimator, [&](const UpdateStats& st, const RangeImuEstimator& e) {
      if (e.latest().t_ns < steady_from) return;
      update_ms.push_back(st.time_s * 1e3);
      cpu_ms.push_back(cpu->last_cpu_s * 1e3);
      tries += st.step_tries;
      ranges += st.factors_added - 1;  // the IMU factor, the rest ranges
      most_states = std::max(most_states, (st.variables_total - static_cast<int>(s.p_w_anchors.size())) / 3);
      error_sum_m += (e.latest().T_w_b.p - s.truthAt(e.latest().t_ns).T_w_b.p).norm();
    });
    std::sort(update_ms.begin(), update_ms.end());
    std::sort(cpu_ms.begin(), cpu_ms.end());
    const double n = static_cast<double>(update_ms.size());
    auto quantile = [&](const std::vector<double>& v, double q) { return v[static_cast<std::size_t>(q * (n - 1))]; };
    state.counters["updates"] = n;
    state.counters["mean_ms"] = std::accumulate(update_ms.begin(), update_ms.end(), 0.0) / n;
    state.counters["p50_ms"] = quantile(update_ms, 0.5);
    state.counters["p99_ms"] = quantile(update_ms, 0.99);
    state.counters["max_ms"] = update_ms.back();
    state.counters["cpu_mean_ms"] = std::accumulate(cpu_ms.begin(), cpu_ms.end(), 0.0) / n;
    state.counters["cpu_p99_ms"] = quantile(cpu_ms, 0.99);
    state.counters["cpu_max_ms"] = cpu_ms.back();
    state.counters["iters_per_upd"] = static_cast<double>(tries) / n;
    state.counters["ranges_per_state"] = static_cast<double>(ranges) / n;
    state.counters["window_states"] = most_states;
    state.counters["online_err_m"] = error_sum_m / n;
  }
}

/// Args: window (s), first-estimate Jacobians (0/1), LM iterations per update (0: default).
void BM_SlidingWindowWalk(benchmark::State& state) {
  const double window_s = static_cast<double>(state.range(0));
  const sim::Scenario& s = fourRangesPerState(window_s + 12.0);  // fill the window, then 12 s in steady state
  SlidingWindowParams params;
  params.window_s = window_s;
  params.first_estimate_jacobians = state.range(1) != 0;
  if (state.range(2) > 0) params.max_iterations = static_cast<int>(state.range(2));
  runAndReport(state, s, window_s, [&] { return std::make_unique<SlidingWindowSmoother>(params); });
}
BENCHMARK(BM_SlidingWindowWalk)
    ->ArgNames({"window_s", "fej", "iters"})
    ->Args({2, 0, 0})
    ->Args({5, 0, 0})
    ->Args({10, 0, 0})
    ->Args({10, 1, 0})
    ->Args({2, 0, 1})
    ->Args({2, 0, 2})
    ->Args({10, 0, 1})
    ->Args({10, 0, 2})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace
}  // namespace rilo

namespace rilo {
namespace {

/// The same walk through the fixed-lag Bayes tree (D-iSAM2 defaults), for
/// comparison. Arg: lag (s).
void BM_BayesTreeSameWalk(benchmark::State& state) {
  const double lag_s = static_cast<double>(state.range(0));
  const sim::Scenario& s = fourRangesPerState(lag_s + 12.0);
  SmootherParams params;
  params.lag_s = lag_s;
  runAndReport(state, s, lag_s, [&] { return std::make_unique<BayesTreeSmoother>(params); });
}
BENCHMARK(BM_BayesTreeSameWalk)->ArgNames({"lag_s"})->Arg(2)->Arg(10)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace
}  // namespace rilo
