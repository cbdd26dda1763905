// Runtime hot paths: SPSC queue push/pop, seqlock hand-over of the
// NavigationState, and the output predictor per IMU sample and per smoother
// hand-over (re-integration of the buffered samples).
#include <benchmark/benchmark.h>

#include <cstdint>
#include <vector>

#include "runtime/latest_value.h"
#include "runtime/output_predictor.h"
#include "runtime/spsc_queue.h"
#include "sim/trajectory.h"

namespace rilo {
namespace {

constexpr double kImuRateHz = 800.0;  // BMI263 in the Ranging-IMU Fusion paper's setup
constexpr std::int64_t kImuPeriodNs = 1'250'000;

// One push and one pop of an ImuSample on the same thread (no contention:
// the cost of the atomics and the copy).
void BM_SpscPushPop(benchmark::State& state) {
  SpscQueue<ImuSample> q(1024);
  ImuSample in, out;
  for (auto _ : state) {
    ++in.t_ns;
    benchmark::DoNotOptimize(q.tryPush(in));
    benchmark::DoNotOptimize(q.tryPop(out));
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_SpscPushPop);

void BM_SeqlockWriteNavigationState(benchmark::State& state) {
  LatestValue<NavigationState> latest;
  NavigationState s;
  for (auto _ : state) {
    ++s.t_ns;
    latest.write(s);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_SeqlockWriteNavigationState);

// Uncontended read (no writer running): the copy plus two counter loads.
void BM_SeqlockReadNavigationState(benchmark::State& state) {
  LatestValue<NavigationState> latest;
  latest.write(NavigationState{});
  NavigationState out;
  for (auto _ : state) {
    benchmark::DoNotOptimize(latest.tryRead(out));
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_SeqlockReadNavigationState);

std::vector<ImuSample> walkSamples(int n) {
  const sim::LissajousWalk walk;
  std::vector<ImuSample> samples(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const sim::ImuReading r = sim::idealImu(walk.at(1.0 + k / kImuRateHz));
    samples[static_cast<std::size_t>(k)].gyro_rad_s = r.gyro;
    samples[static_cast<std::size_t>(k)].accel_m_s2 = r.accel;
  }
  return samples;
}

NavigationState startState() {
  const sim::KinematicState k = sim::LissajousWalk().at(1.0);
  NavigationState s;
  s.q_w_b = Quat(k.T_w_b.R);
  s.p_w_b = k.T_w_b.p;
  s.v_w_b = k.v_w;
  s.valid = true;
  return s;
}

// One IMU sample through the predictor: buffer, integrate, covariance.
void BM_OutputPredictorOnImu(benchmark::State& state) {
  const std::vector<ImuSample> samples = walkSamples(static_cast<int>(kImuRateHz));
  OutputPredictor pred;
  pred.onSmoothed(startState());
  std::int64_t t_ns = 0;
  std::size_t k = 0;
  for (auto _ : state) {
    ImuSample s = samples[k];
    t_ns += kImuPeriodNs;  // time keeps increasing while the motion data repeats
    s.t_ns = t_ns;
    benchmark::DoNotOptimize(pred.onImu(s).p_w_b);
    if (++k == samples.size()) k = 0;
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_OutputPredictorOnImu);

// A smoother hand-over re-integrating Arg samples (800 Hz: 40 = 50 ms of
// smoother delay, 800 = 1 s as with 1 Hz ranging).
void BM_OutputPredictorOnSmoothed(benchmark::State& state) {
  const auto n = static_cast<int>(state.range(0));
  const std::vector<ImuSample> samples = walkSamples(n);
  OutputPredictor pred;
  for (int k = 0; k < n; ++k) {
    ImuSample s = samples[static_cast<std::size_t>(k)];
    s.t_ns = (k + 1) * kImuPeriodNs;
    pred.onImu(s);
  }
  const NavigationState smoothed = startState();  // t_ns = 0: every buffered sample is newer
  for (auto _ : state) benchmark::DoNotOptimize(pred.onSmoothed(smoothed).p_w_b);
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * n);
}
BENCHMARK(BM_OutputPredictorOnSmoothed)->Arg(40)->Arg(800);

}  // namespace
}  // namespace rilo
