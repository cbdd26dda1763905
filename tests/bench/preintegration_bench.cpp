// IMU-rate hot path: one preintegration step, and linearizing the IMU factors.
#include <benchmark/benchmark.h>

#include <vector>

#include "estimation/factors/imu_factor.h"
#include "sim/trajectory.h"

namespace rilo {
namespace {

constexpr double kRateHz = 800.0;  // BMI263 in the Ranging-IMU Fusion paper's setup

std::vector<sim::ImuReading> walkSamples(int n, double t0_s = 1.0) {
  const sim::LissajousWalk walk;
  std::vector<sim::ImuReading> samples;
  samples.reserve(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) samples.push_back(sim::idealImu(walk.at(t0_s + k / kRateHz)));
  return samples;
}

// ns per integrate() call, in windows of 1 s (800 samples) as between two
// states at 1 Hz ranging; the reset per window is included (amortized).
// Arg: CovarianceMode (0 = 9x9 for ImuFactor, 1 = 15x15 for CombinedImuFactor, 2 = both).
void BM_PreintegrateSample(benchmark::State& state) {
  const std::vector<sim::ImuReading> samples = walkSamples(static_cast<int>(kRateHz));
  const ImuBias bias_hat(Vec3(0.02, -0.01, 0.03), Vec3(0.001, 0.002, -0.001));
  const auto mode = static_cast<PreintegratedImu::CovarianceMode>(state.range(0));
  PreintegratedImu pim{ImuParams(), bias_hat, mode};
  std::size_t k = 0;
  for (auto _ : state) {
    if (k == samples.size()) {
      k = 0;
      pim.reset(bias_hat);
    }
    pim.integrate(samples[k].accel, samples[k].gyro, 1.0 / kRateHz);
    ++k;
    benchmark::DoNotOptimize(pim);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_PreintegrateSample)->ArgName("mode")->Arg(0)->Arg(1)->Arg(2);

struct FactorFixture {
  PreintegratedImu pim{ImuParams()};
  Values x;
  explicit FactorFixture(double T_s) {
    const sim::LissajousWalk walk;
    const int n = static_cast<int>(T_s * kRateHz);
    for (const auto& m : walkSamples(n)) pim.integrate(m.accel, m.gyro, 1.0 / kRateHz);
    const sim::KinematicState si = walk.at(1.0), sj = walk.at(1.0 + n / kRateHz);
    x.insert(sym::X(0), si.T_w_b);
    x.insert(sym::V(0), si.v_w);
    x.insert(sym::B(0), ImuBias(Vec3(0.01, 0.02, 0.03), Vec3(0.001, -0.001, 0.002)));
    x.insert(sym::X(1), sj.T_w_b);
    x.insert(sym::V(1), sj.v_w);
    x.insert(sym::B(1), ImuBias());
  }
};

// Whitened residual and all six 15x6/15x3 Jacobian blocks (window 1 s).
void BM_CombinedImuFactorLinearize(benchmark::State& state) {
  const FactorFixture fx(1.0);
  const CombinedImuFactor f(sym::X(0), sym::V(0), sym::B(0), sym::X(1), sym::V(1), sym::B(1), fx.pim);
  Residual r;
  Jacobians H;
  for (auto _ : state) {
    benchmark::DoNotOptimize(f.linearize(fx.x, r, H));
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_CombinedImuFactorLinearize);

void BM_ImuFactorLinearize(benchmark::State& state) {
  const FactorFixture fx(1.0);
  const ImuFactor f(sym::X(0), sym::V(0), sym::X(1), sym::V(1), sym::B(0), fx.pim);
  Residual r;
  Jacobians H;
  for (auto _ : state) {
    benchmark::DoNotOptimize(f.linearize(fx.x, r, H));
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_ImuFactorLinearize);

// One-off cost when a state is created: copy of the preintegration, 15x15
// Cholesky and triangular inverse.
void BM_CombinedImuFactorConstruct(benchmark::State& state) {
  const FactorFixture fx(1.0);
  for (auto _ : state) {
    const CombinedImuFactor f(sym::X(0), sym::V(0), sym::B(0), sym::X(1), sym::V(1), sym::B(1), fx.pim);
    benchmark::DoNotOptimize(f.sqrtInformation().data());
  }
}
BENCHMARK(BM_CombinedImuFactorConstruct);

}  // namespace
}  // namespace rilo
