// Cost of linearizing one UWB range factor (evaluate + Jacobians + IRLS
// weighting), the per-measurement work of every smoother update.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <memory>
#include <random>

#include "estimation/factors/range_factor.h"
#include "math/so3.h"

namespace rilo {
namespace {

// Huber-shaped loss local to the benchmark, so it measures the factor and not
// a particular loss implementation (same virtual-call structure).
class BenchHuber final : public RobustLoss {
 public:
  double loss(double r) const override {
    const double a = std::abs(r);
    return a <= kK ? 0.5 * r * r : kK * (a - 0.5 * kK);
  }
  double derivative(double r) const override { return std::abs(r) <= kK ? r : kK * (r > 0 ? 1.0 : -1.0); }
  std::string name() const override { return "bench_huber"; }

 private:
  static constexpr double kK = 1.345;
};

constexpr int kNumFactors = 16;

struct RangeSetup {
  Values values;
  std::array<std::unique_ptr<RangeFactor>, kNumFactors> factors;
};

// 16 factors on one pose with random measurements (half inside the Huber
// core, half in its tails), anchors as variables (arg 1) or constants (arg 0).
RangeSetup makeSetup(bool anchor_variable) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  RangeSetup s;
  const Pose3 T_w_b(so3::exp(Vec3(0.1, -0.2, 1.3)), Vec3(2.0, 1.0, 1.2));
  const Vec3 p_b_tag(0.05, 0.0, 0.15);
  s.values.insert(sym::X(0), T_w_b);
  auto loss = std::make_shared<BenchHuber>();
  for (int j = 0; j < kNumFactors; ++j) {
    const Vec3 p_w_anchor(5.0 * n(rng), 5.0 * n(rng), 2.5 + 0.3 * n(rng));
    const double sigma = 0.1;
    const double offset = (j % 2 == 0 ? 0.5 : 4.0) * sigma * (n(rng) > 0 ? 1.0 : -1.0);
    const double z = (T_w_b.transformFrom(p_b_tag) - p_w_anchor).norm() + offset;
    const auto jj = static_cast<std::uint64_t>(j);
    if (anchor_variable) {
      s.values.insert(sym::L(jj), p_w_anchor);
      s.factors[static_cast<std::size_t>(j)] =
          std::make_unique<RangeFactor>(sym::X(0), sym::L(jj), z, sigma, p_b_tag, loss);
    } else {
      s.factors[static_cast<std::size_t>(j)] =
          std::make_unique<RangeFactor>(sym::X(0), p_w_anchor, z, sigma, p_b_tag, loss);
    }
  }
  return s;
}

void BM_RangeFactorLinearize(benchmark::State& state) {
  const RangeSetup s = makeSetup(state.range(0) != 0);
  Residual r;
  Jacobians H;
  std::size_t i = 0;
  for (auto _ : state) {
    const double w = s.factors[i]->linearize(s.values, r, H);
    benchmark::DoNotOptimize(w);
    benchmark::DoNotOptimize(r.data());
    benchmark::DoNotOptimize(H[0].data());
    i = (i + 1) % kNumFactors;
  }
  state.SetLabel(state.range(0) != 0 ? "anchor variable" : "anchor constant");
}
BENCHMARK(BM_RangeFactorLinearize)->Arg(0)->Arg(1);

void BM_RangeFactorError(benchmark::State& state) {
  const RangeSetup s = makeSetup(state.range(0) != 0);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(s.factors[i]->error(s.values));
    i = (i + 1) % kNumFactors;
  }
  state.SetLabel(state.range(0) != 0 ? "anchor variable" : "anchor constant");
}
BENCHMARK(BM_RangeFactorError)->Arg(0)->Arg(1);

}  // namespace
}  // namespace rilo
