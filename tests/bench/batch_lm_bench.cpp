// Batch LM on a synthetic pose chain: Pose3 between factors, a prior on the
// first pose and ranges from every pose to 5 known anchors (bench-local
// factors; the range+IMU benchmark on the real factors lives elsewhere).
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "estimation/solver/batch_lm.h"
#include "estimation/solver/normal_equations.h"
#include "estimation/solver/ordering.h"
#include "math/so3.h"

namespace rilo {
namespace {

class BenchPosePrior : public Factor {
 public:
  BenchPosePrior(Key k, const Pose3& z, double sigma) : Factor({k}), z_(z), w_(1.0 / sigma) {}
  int dim() const override { return 6; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    const Pose3& T = x.pose(keys()[0]);
    const Vec6 e = z_.local(T);
    r = w_ * e;
    if (H) {
      (*H)[0].setZero(6, 6);
      (*H)[0].block<3, 3>(0, 0) = w_ * so3::rightJacobianInverse(e.head<3>());
      (*H)[0].block<3, 3>(3, 3) = w_ * z_.R.transpose() * T.R;
    }
  }

 private:
  Pose3 z_;
  double w_;
};

class BenchPoseBetween : public Factor {
 public:
  BenchPoseBetween(Key i, Key j, const Pose3& z, double sigma_rot, double sigma_pos)
      : Factor({i, j}), z_(z), w_rot_(1.0 / sigma_rot), w_pos_(1.0 / sigma_pos) {}
  int dim() const override { return 6; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    const Pose3& Ti = x.pose(keys()[0]);
    const Pose3& Tj = x.pose(keys()[1]);
    const Vec3 d = Ti.R.transpose() * (Tj.p - Ti.p);
    const Vec3 e_rot = so3::log(z_.R.transpose() * Ti.R.transpose() * Tj.R);
    r.resize(6);
    r.head<3>() = w_rot_ * e_rot;
    r.tail<3>() = w_pos_ * z_.R.transpose() * (d - z_.p);
    if (H) {
      const Mat3 Jr_inv = so3::rightJacobianInverse(e_rot);
      (*H)[0].setZero(6, 6);
      (*H)[1].setZero(6, 6);
      (*H)[0].block<3, 3>(0, 0) = -w_rot_ * Jr_inv * Tj.R.transpose() * Ti.R;
      (*H)[0].block<3, 3>(3, 0) = w_pos_ * z_.R.transpose() * so3::hat(d);
      (*H)[0].block<3, 3>(3, 3) = -w_pos_ * z_.R.transpose();
      (*H)[1].block<3, 3>(0, 0) = w_rot_ * Jr_inv;
      (*H)[1].block<3, 3>(3, 3) = w_pos_ * z_.R.transpose() * Ti.R.transpose() * Tj.R;
    }
  }

 private:
  Pose3 z_;
  double w_rot_, w_pos_;
};

class BenchRange : public Factor {
 public:
  BenchRange(Key k, const Vec3& a_w, double range_m, double sigma)
      : Factor({k}), a_w_(a_w), range_m_(range_m), w_(1.0 / sigma) {}
  int dim() const override { return 1; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    const Pose3& T = x.pose(keys()[0]);
    const Vec3 diff = T.p - a_w_;
    const double dist = diff.norm();
    r.resize(1);
    r(0) = w_ * (range_m_ - dist);
    if (H) {
      (*H)[0].setZero(1, 6);
      (*H)[0].block<1, 3>(0, 3) = -w_ * diff.transpose() * T.R / dist;
    }
  }

 private:
  Vec3 a_w_;
  double range_m_;
  double w_;
};

struct ChainProblem {
  FactorGraph graph;
  Values initial;
};

ChainProblem makeChain(int n_poses) {
  std::mt19937 rng(42);
  std::normal_distribution<double> noise(0.0, 1.0);
  auto vec = [&](double s) { return Vec3(s * noise(rng), s * noise(rng), s * noise(rng)); };
  const Vec3 anchors[] = {Vec3(0, 0, 0.2), Vec3(12, 0, 2.8), Vec3(0, 11, 1.5), Vec3(12, 11, 0.4), Vec3(6, 5, 3.5)};
  std::vector<Pose3> truth;
  for (int i = 0; i < n_poses; ++i) {
    const double t = 0.05 * i;
    truth.emplace_back(so3::exp(Vec3(0.1 * std::sin(t), 0.1 * std::cos(t), t)),
                       Vec3(6 + 4 * std::cos(t), 5 + 3 * std::sin(1.3 * t), 1.2 + 0.2 * std::sin(2 * t)));
  }
  ChainProblem p;
  p.graph.emplace<BenchPosePrior>(sym::X(0), truth[0], 0.01);
  for (int i = 0; i + 1 < n_poses; ++i) {
    const Pose3& Ti = truth[static_cast<std::size_t>(i)];
    const Pose3& Tj = truth[static_cast<std::size_t>(i + 1)];
    Vec6 xi;
    xi << vec(0.005), vec(0.02);
    const Pose3 z = Pose3(Ti.R.transpose() * Tj.R, Ti.R.transpose() * (Tj.p - Ti.p)).retract(xi);
    p.graph.emplace<BenchPoseBetween>(sym::X(static_cast<std::uint64_t>(i)), sym::X(static_cast<std::uint64_t>(i + 1)),
                                      z, 0.005, 0.02);
  }
  for (int i = 0; i < n_poses; ++i) {
    for (const Vec3& a : anchors) {
      const double z = (truth[static_cast<std::size_t>(i)].p - a).norm() + 0.05 * noise(rng);
      p.graph.emplace<BenchRange>(sym::X(static_cast<std::uint64_t>(i)), a, z, 0.05);
    }
  }
  for (int i = 0; i < n_poses; ++i) {
    Vec6 xi;
    xi << vec(0.05), vec(0.3);
    p.initial.insert(sym::X(static_cast<std::uint64_t>(i)), truth[static_cast<std::size_t>(i)].retract(xi));
  }
  return p;
}

void reportResult(benchmark::State& state, const LmResult& r) {
  state.counters["iterations"] = r.iterations;
  state.counters["factorizations"] = r.factorizations;
  state.counters["final_error"] = r.final_error;
  state.counters["converged"] = r.converged() ? 1 : 0;
}

// Full solve with a fresh solver: ordering, pattern and symbolic analysis included.
void BM_BatchLmChain(benchmark::State& state) {
  const ChainProblem p = makeChain(static_cast<int>(state.range(0)));
  LmResult last;
  for (auto _ : state) {
    BatchLevenbergMarquardt lm;
    auto out = lm.optimize(p.graph, p.initial);
    benchmark::DoNotOptimize(out.values);
    last = std::move(out.result);
  }
  reportResult(state, last);
}
BENCHMARK(BM_BatchLmChain)->Arg(100)->Arg(300)->Arg(1000)->Unit(benchmark::kMillisecond);

// Same problem on a solver that already holds the structure (re-solves reuse
// ordering, Hessian pattern and CHOLMOD's analysis).
void BM_BatchLmChainWarm(benchmark::State& state) {
  const ChainProblem p = makeChain(static_cast<int>(state.range(0)));
  BatchLevenbergMarquardt lm;
  (void)lm.optimize(p.graph, p.initial);
  LmResult last;
  for (auto _ : state) {
    auto out = lm.optimize(p.graph, p.initial);
    benchmark::DoNotOptimize(out.values);
    last = std::move(out.result);
  }
  reportResult(state, last);
}
BENCHMARK(BM_BatchLmChainWarm)->Arg(100)->Arg(300)->Arg(1000)->Unit(benchmark::kMillisecond);

// One linearization (all factors) into the preallocated Hessian.
void BM_NormalEquationsLinearize(benchmark::State& state) {
  const ChainProblem p = makeChain(static_cast<int>(state.range(0)));
  NormalEquations ne;
  ne.setStructure(p.graph, p.initial, colamdOrdering(p.graph));
  for (auto _ : state) {
    ne.linearize(p.graph, p.initial);
    benchmark::DoNotOptimize(ne.hessianValues().data());
  }
  state.counters["nnz"] = ne.nonzeros();
}
BENCHMARK(BM_NormalEquationsLinearize)->Arg(300)->Unit(benchmark::kMicrosecond);

// One numeric factorization + solve of the (damped) Hessian.
void BM_CholmodFactorizeSolve(benchmark::State& state) {
  const ChainProblem p = makeChain(static_cast<int>(state.range(0)));
  NormalEquations ne;
  ne.setStructure(p.graph, p.initial, colamdOrdering(p.graph));
  ne.linearize(p.graph, p.initial);
  CholmodContext ctx;
  CholmodFactor factor;
  (void)ctx.analyze(ne.hessian(), {}, AnalyzeOptions{.postorder = true}, &factor);
  Eigen::VectorXd x(ne.dim());
  const Eigen::VectorXd b = -ne.gradient();
  for (auto _ : state) {
    const CholmodResult f =
        ctx.factorize(ne.hessian(), FactorizeOptions{.shift = 1e-6, .min_pivot_ratio = 1e-12}, factor);
    const CholmodResult s = ctx.solve(factor, b.data(), 1, x.data());
    benchmark::DoNotOptimize(x.data());
    if (!f.ok() || !s.ok()) state.SkipWithError("factorization failed");
  }
  state.counters["nnz_L"] = factor.factorNonzeros();
  state.counters["supernodal"] = factor.isSupernodal() ? 1 : 0;
}
BENCHMARK(BM_CholmodFactorizeSolve)->Arg(300)->Arg(1000)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace rilo
