// Cost of one IRLS weight evaluation of the range losses, over a spread of
// whitened residuals: mostly LOS-like (N(0,1)), some NLOS excesses (half-Cauchy
// with scale 5 added), so every branch (Gaussian core, table, asymptote) runs.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/huber_loss.h"
#include "estimation/noise/noise_model_factory.h"

namespace {

std::vector<double> residualSpread() {
  std::mt19937 rng(7);
  std::normal_distribution<double> los(0.0, 1.0);
  std::cauchy_distribution<double> nlos(0.0, 5.0);
  std::bernoulli_distribution is_nlos(0.3);
  std::vector<double> r(4096);
  for (double& x : r) x = los(rng) + (is_nlos(rng) ? std::abs(nlos(rng)) : 0.0);
  return r;
}

template <class Loss>
void runWeights(benchmark::State& state, const Loss& loss) {
  const std::vector<double> r = residualSpread();
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(loss.weight(r[i]));
    i = (i + 1) & (r.size() - 1);
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_AsymmetricLossWeight(benchmark::State& state) {
  const rilo::AsymmetricLoss loss(rilo::RangeNoiseParams::kGaussianIqrPerSigma, 0.2);
  runWeights(state, loss);
}
BENCHMARK(BM_AsymmetricLossWeight);

void BM_AsymmetricHalfCauchyWeight(benchmark::State& state) {
  const rilo::AsymmetricLoss loss(rilo::RangeNoiseParams::kGaussianIqrPerSigma, 0.2,
                                  rilo::AsymmetricLoss::Component::kHalfCauchy);
  runWeights(state, loss);
}
BENCHMARK(BM_AsymmetricHalfCauchyWeight);

// Only the NLOS (tabulated) branch: residuals in [3, 300].
void BM_AsymmetricLossWeightNlosOnly(benchmark::State& state) {
  const rilo::AsymmetricLoss loss(rilo::RangeNoiseParams::kGaussianIqrPerSigma, 0.2);
  std::vector<double> r(4096);
  for (std::size_t k = 0; k < r.size(); ++k) r[k] = 3.0 * std::pow(100.0, static_cast<double>(k) / 4096.0);
  std::mt19937 rng(3);
  std::shuffle(r.begin(), r.end(), rng);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(loss.weight(r[i]));
    i = (i + 1) & (r.size() - 1);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_AsymmetricLossWeightNlosOnly);

void BM_HuberWeight(benchmark::State& state) {
  const rilo::HuberLoss loss;
  runWeights(state, loss);
}
BENCHMARK(BM_HuberWeight);

void BM_AsymmetricLossConstruction(benchmark::State& state) {
  for (auto _ : state) {
    rilo::AsymmetricLoss loss(rilo::RangeNoiseParams::kGaussianIqrPerSigma, 0.2);
    benchmark::DoNotOptimize(loss.decisionPoint());
  }
}
BENCHMARK(BM_AsymmetricLossConstruction)->Unit(benchmark::kMillisecond);

}  // namespace
