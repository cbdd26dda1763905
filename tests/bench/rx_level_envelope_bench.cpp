// The RX-level indicator on the range path: per range one add() (a refit of
// the 2048-range window every 64th) and one deficitDb(), as
// Localizer::withRxLevelIndicator calls them for ranges without first-path power.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "estimation/measurements/rx_level_envelope.h"

namespace rilo {
namespace {

// ns per range, the refits amortized over their 64 ranges.
void BM_RxLevelEnvelopePerRange(benchmark::State& state) {
  RxLevelEnvelope env;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> range(2.0, 30.0), loss(0.0, 12.0);
  double deficit = 0.0;
  for (auto _ : state) {
    const double d = range(rng);
    const double rssi = -42.0 - 20.0 * std::log10(d) - loss(rng);
    env.add(d, rssi);
    deficit = env.deficitDb(d, rssi);
    benchmark::DoNotOptimize(deficit);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_RxLevelEnvelopePerRange);

}  // namespace
}  // namespace rilo
