// The standstill test on the tracking path: per IMU sample one add(), per
// state one stillOver() over the trailing 0.5 s (400 samples at 800 Hz) and
// one dropBefore(), as RangeImuGraphStream and EkfEstimator call them.
#include <benchmark/benchmark.h>

#include <cmath>

#include "estimation/measurements/standstill.h"

namespace rilo {
namespace {

constexpr std::int64_t kImuDtNs = 1'250'000;  // 800 Hz

// ns per state; Arg: ranging (state) rate in Hz.
void BM_StandstillPerState(benchmark::State& state) {
  const int samples_per_state = static_cast<int>(800 / state.range(0));
  StandstillDetector d;
  ImuSample s;
  s.accel_m_s2 = Vec3(0.0, 0.0, 9.81);
  std::int64_t t = 0, t_prev = 0;
  bool still = false;
  for (auto _ : state) {
    for (int k = 0; k < samples_per_state; ++k, t += kImuDtNs) {
      s.t_ns = t;
      s.accel_m_s2.x() = 0.02 * std::sin(static_cast<double>(t) * 1e-8);
      d.add(s);
    }
    still = d.stillFor(t_prev, t, Vec3::Zero());
    benchmark::DoNotOptimize(still);
    d.dropBefore(t);
    t_prev = t;
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_StandstillPerState)->Arg(40)->Arg(1);

}  // namespace
}  // namespace rilo
