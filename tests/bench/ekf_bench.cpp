// Error-state EKF hot paths: one IMU propagation (midpoint step + 15x15
// covariance), one scalar range / TDoA update and one 2-row ultrasonic update
// (gate, robust re-weighting, Joseph form, injection and reset).
#include <benchmark/benchmark.h>

#include <array>
#include <random>
#include <vector>

#include "estimation/ekf/error_state_ekf.h"
#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/huber_loss.h"
#include "sim/trajectory.h"

namespace rilo {
namespace {

constexpr double kImuRateHz = 800.0;  // BMI263 in the Ranging-IMU Fusion paper's setup
constexpr int kNumAnchors = 8;

Mat15 startCovariance() {
  Vec15 s;
  s << Vec3::Constant(0.05), Vec3::Constant(0.3), Vec3::Constant(0.2), Vec3::Constant(0.03),
      Vec3::Constant(0.003);
  return s.cwiseAbs2().asDiagonal();
}

ErrorStateEkf startedFilter() {
  const sim::KinematicState s0 = sim::LissajousWalk().at(1.0);
  ErrorStateEkf ekf;
  ekf.initialize(0, EkfState(s0.T_w_b, s0.v_w, ImuBias()), startCovariance());
  return ekf;
}

// ns per propagate() on the walk at 800 Hz; restarted every 800 samples (amortized).
void BM_EkfPropagate(benchmark::State& state) {
  const sim::LissajousWalk walk;
  std::vector<ImuSample> samples;
  for (int k = 0; k < static_cast<int>(kImuRateHz); ++k) {
    const sim::ImuReading m = sim::idealImu(walk.at(1.0 + k / kImuRateHz));
    ImuSample s;
    s.t_ns = static_cast<std::int64_t>(k * 1e9 / kImuRateHz);
    s.gyro_rad_s = m.gyro;
    s.accel_m_s2 = m.accel;
    samples.push_back(s);
  }
  const ErrorStateEkf start = startedFilter();
  ErrorStateEkf ekf = start;
  std::size_t k = 0;
  for (auto _ : state) {
    if (k == samples.size()) {
      k = 0;
      ekf = start;
    }
    benchmark::DoNotOptimize(ekf.propagate(samples[k++]));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_EkfPropagate);

struct UpdateSetup {
  ErrorStateEkf start = startedFilter();
  std::array<Vec3, kNumAnchors> anchors;
  std::array<double, kNumAnchors> ranges;    ///< TWR, with noise
  std::array<double, kNumAnchors> diffs;     ///< TDoA against anchor 0, with noise
  Vec3 p_b_tag{0.1, 0.0, 0.2};
  UpdateSetup() {
    std::mt19937 rng(5);
    std::normal_distribution<double> n(0.0, 1.0);
    const EkfState& x = start.state();
    for (int j = 0; j < kNumAnchors; ++j) {
      const auto jj = static_cast<std::size_t>(j);
      anchors[jj] = Vec3((j & 1) ? 6.0 : -6.0, (j & 2) ? 5.0 : -5.0, (j & 4) ? 2.6 : 0.4);
      ranges[jj] = predictRange(x, anchors[jj], p_b_tag).h(0) + 0.1 * n(rng);
      diffs[jj] = predictTdoa(x, anchors[0], anchors[jj], p_b_tag).h(0) + 0.1 * n(rng);
    }
  }
};

// Arg: loss (0 none, 1 Huber, 2 asymmetric NLOS). Cycles the 8 anchors; the
// filter is restored every 64 updates so the covariance stays realistic.
void BM_EkfUpdateRange(benchmark::State& state) {
  const UpdateSetup s;
  const HuberLoss huber;
  const AsymmetricLoss nlos(5.0, 0.2);
  const RobustLoss* loss = state.range(0) == 1 ? static_cast<const RobustLoss*>(&huber)
                           : state.range(0) == 2 ? static_cast<const RobustLoss*>(&nlos)
                                                 : nullptr;
  ErrorStateEkf ekf = s.start;
  std::size_t i = 0;
  for (auto _ : state) {
    if (i % 64 == 0) ekf = s.start;
    const std::size_t j = i++ % kNumAnchors;
    benchmark::DoNotOptimize(ekf.updateRange(s.anchors[j], s.p_b_tag, s.ranges[j], 0.1, loss));
  }
  state.SetLabel(state.range(0) == 0 ? "gaussian" : state.range(0) == 1 ? "huber" : "asymmetric");
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_EkfUpdateRange)->ArgName("loss")->Arg(0)->Arg(1)->Arg(2);

void BM_EkfUpdateTdoa(benchmark::State& state) {
  const UpdateSetup s;
  ErrorStateEkf ekf = s.start;
  std::size_t i = 0;
  for (auto _ : state) {
    if (i % 64 == 0) ekf = s.start;
    const std::size_t j = 1 + i++ % (kNumAnchors - 1);
    benchmark::DoNotOptimize(ekf.updateTdoa(s.anchors[0], s.anchors[j], s.p_b_tag, s.diffs[j], 0.1));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_EkfUpdateTdoa);

// 2-row update (range + elevation), 2x2 innovation covariance.
void BM_EkfUpdateUltrasonicElevation(benchmark::State& state) {
  const UpdateSetup s;
  const Vec3 beacon(0.0, 0.0, 2.8);
  const EkfState& x = s.start.state();
  const double z = predictUltrasonic(x, beacon, s.p_b_tag).h(0) + 0.01;
  const UltrasonicElevation elev{predictUltrasonic(x, beacon, s.p_b_tag).h(1) + 0.02, 0.1};
  ErrorStateEkf ekf = s.start;
  std::size_t i = 0;
  for (auto _ : state) {
    if (i++ % 64 == 0) ekf = s.start;
    benchmark::DoNotOptimize(ekf.updateUltrasonic(beacon, s.p_b_tag, z, 0.02, elev));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_EkfUpdateUltrasonicElevation);

}  // namespace
}  // namespace rilo
