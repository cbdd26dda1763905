#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/cauchy_loss.h"
#include "estimation/noise/gaussian_loss.h"
#include "estimation/noise/huber_loss.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {
namespace {

constexpr double kPi = 3.14159265358979323846;
using Component = AsymmetricLoss::Component;

// ---------------------------------------------------------------------------
// Properties every loss must have (robust_loss.h conventions).

struct LossCase {
  std::string label;
  std::function<RobustLossPtr()> make;
};

std::vector<LossCase> allLossCases() {
  return {
      {"Gaussian", [] { return std::make_shared<GaussianLoss>(); }},
      {"HuberDefault", [] { return std::make_shared<HuberLoss>(); }},
      {"HuberK0p5", [] { return std::make_shared<HuberLoss>(0.5); }},
      {"CauchyDefault", [] { return std::make_shared<CauchyLoss>(); }},
      {"CauchyC1", [] { return std::make_shared<CauchyLoss>(1.0); }},
      {"AsymFactoryDefault", [] { return makeRangeLoss("asymmetric"); }},
      {"AsymGamma0p5W0p1", [] { return std::make_shared<AsymmetricLoss>(0.5, 0.1); }},
      {"AsymGamma5W0p3", [] { return std::make_shared<AsymmetricLoss>(5.0, 0.3); }},
      {"AsymGamma0p01W0p45", [] { return std::make_shared<AsymmetricLoss>(0.01, 0.45); }},
      {"AsymGammaMinW0p2", [] { return std::make_shared<AsymmetricLoss>(AsymmetricLoss::kMinGamma, 0.2); }},
      {"AsymGammaMaxW0p05", [] { return std::make_shared<AsymmetricLoss>(AsymmetricLoss::kMaxGamma, 0.05); }},
      // Mode of g beyond the crossing: the clamped NLOS branch.
      {"AsymClampedGamma100W0p2", [] { return std::make_shared<AsymmetricLoss>(100.0, 0.2); }},
      {"AsymClampedGamma20W0p49", [] { return std::make_shared<AsymmetricLoss>(20.0, 0.49); }},
      {"HalfCauchyFactoryDefault", [] { return makeRangeLoss("asymmetric-half-cauchy"); }},
      {"HalfCauchyGamma20W0p4", [] { return std::make_shared<AsymmetricLoss>(20.0, 0.4, Component::kHalfCauchy); }},
  };
}

class AnyLoss : public ::testing::TestWithParam<LossCase> {
 protected:
  void SetUp() override {
    loss_ = GetParam().make();
    ASSERT_NE(loss_, nullptr);
    if (const auto* a = dynamic_cast<const AsymmetricLoss*>(loss_.get())) kink_ = a->decisionPoint();
  }
  /// Residuals covering the core, both tails and the table's far end.
  static std::vector<double> sampleResiduals() {
    std::vector<double> r;
    for (double x = -40.0; x <= 40.0; x += 0.01237) r.push_back(x);
    for (double x = 1e-6; x < 1e7; x *= 1.05) {
      r.push_back(x);
      r.push_back(-x);
    }
    std::sort(r.begin(), r.end());
    return r;
  }
  RobustLossPtr loss_;
  double kink_ = std::numeric_limits<double>::quiet_NaN();  ///< max-mixture kink, if any
};

TEST_P(AnyLoss, ZeroAtOriginWithUnitWeight) {
  EXPECT_EQ(loss_->loss(0.0), 0.0);
  EXPECT_EQ(loss_->derivative(0.0), 0.0);
  EXPECT_EQ(loss_->weight(0.0), 1.0);
}

TEST_P(AnyLoss, QuadraticCore) {
  for (double r : {1e-8, 1e-6, 1e-4, 1e-3, 1e-2}) {
    for (double sr : {r, -r}) {
      EXPECT_NEAR(loss_->loss(sr), 0.5 * sr * sr, r * r * r) << "r " << sr;
      EXPECT_NEAR(loss_->derivative(sr), sr, r * r) << "r " << sr;
      EXPECT_NEAR(loss_->weight(sr), 1.0, r) << "r " << sr;
    }
  }
}

TEST_P(AnyLoss, ContinuousUnderDenseSampling) {
  // |rho(b) - rho(a)| is bounded by the larger end slope times the step; a
  // jump (e.g. a mis-placed max-mixture switch) breaks that bound.
  std::vector<double> r;
  for (double x = -60.0; x <= 60.0; x += 1e-3) r.push_back(x);
  for (double x = 60.0; x < 2e5; x *= 1.0005) r.push_back(x);
  if (std::isfinite(kink_)) {
    for (double d = -1e-3; d <= 1e-3; d += 1e-6) r.push_back(kink_ + d);
    r.push_back(AsymmetricLoss::kTableMaxEps * (1 - 1e-12));
    r.push_back(AsymmetricLoss::kTableMaxEps * (1 + 1e-12));
  }
  std::sort(r.begin(), r.end());
  for (std::size_t i = 0; i + 1 < r.size(); ++i) {
    const double a = r[i], b = r[i + 1];
    const double slope = std::max(std::abs(loss_->derivative(a)), std::abs(loss_->derivative(b)));
    ASSERT_LE(std::abs(loss_->loss(b) - loss_->loss(a)), 1.01 * slope * (b - a) + 1e-9)
        << "jump between " << a << " and " << b;
  }
}

TEST_P(AnyLoss, NonDecreasingInMagnitudeOnEachSide) {
  const std::vector<double> r = sampleResiduals();
  double prev_pos = 0.0;
  double prev_neg = 0.0;
  for (double x : r) {
    if (x <= 0.0) continue;
    const double pos = loss_->loss(x);
    ASSERT_GE(pos, prev_pos - 1e-12 * (1 + pos)) << "r " << x;
    prev_pos = pos;
  }
  for (auto it = r.rbegin(); it != r.rend(); ++it) {
    if (*it >= 0.0) continue;
    const double neg = loss_->loss(*it);
    ASSERT_GE(neg, prev_neg - 1e-12 * (1 + neg)) << "r " << *it;
    prev_neg = neg;
  }
}

TEST_P(AnyLoss, DerivativeMatchesCentralDifference) {
  int checked = 0;
  for (double r : sampleResiduals()) {
    const double h = 1e-5 * std::max(1.0, std::abs(r));
    if (std::isfinite(kink_) && std::abs(r - kink_) < 3 * h) continue;  // max-mixture switch
    const double fd = (loss_->loss(r + h) - loss_->loss(r - h)) / (2 * h);
    const double d = loss_->derivative(r);
    // Truncation (h^2 rho''' / 6) is covered by the relative term, rounding by the last.
    const double tol = 1e-6 * std::abs(d) + 1e-10 + 1e-15 * std::abs(loss_->loss(r)) / h;
    ASSERT_NEAR(d, fd, tol) << "r " << r;
    ++checked;
  }
  EXPECT_GT(checked, 1000);
}

TEST_P(AnyLoss, WeightIsDerivativeOverResidualAndNonNegative) {
  for (double r : sampleResiduals()) {
    if (r == 0.0) continue;
    const double w = loss_->weight(r);
    EXPECT_GE(w, 0.0) << "r " << r;
    EXPECT_LE(w, 1.0 + 1e-12) << "r " << r;  // none of our losses up-weights
    EXPECT_NEAR(w, loss_->derivative(r) / r, 1e-14 * std::max(1.0, w)) << "r " << r;
  }
}

TEST_P(AnyLoss, SymmetricLossesAreSymmetric) {
  if (!loss_->isSymmetric()) {
    EXPECT_NE(dynamic_cast<const AsymmetricLoss*>(loss_.get()), nullptr);
    return;
  }
  for (double r : sampleResiduals()) {
    EXPECT_EQ(loss_->loss(r), loss_->loss(-r));
    EXPECT_EQ(loss_->derivative(r), -loss_->derivative(-r));
    EXPECT_EQ(loss_->weight(r), loss_->weight(-r));
  }
}

TEST_P(AnyLoss, NonFiniteInputsDoNotCrash) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(loss_->loss(-inf), inf);
  EXPECT_TRUE(std::isnan(loss_->loss(std::numeric_limits<double>::quiet_NaN())));
  EXPECT_GE(loss_->weight(inf), 0.0);
}

INSTANTIATE_TEST_SUITE_P(Noise, AnyLoss, ::testing::ValuesIn(allLossCases()),
                         [](const ::testing::TestParamInfo<LossCase>& case_info) { return case_info.param.label; });

// ---------------------------------------------------------------------------
// Simple losses: exact formulas.

TEST(HuberLoss, MatchesDefinition) {
  const HuberLoss h(1.5);
  EXPECT_DOUBLE_EQ(h.loss(1.0), 0.5);
  EXPECT_DOUBLE_EQ(h.loss(-3.0), 1.5 * 3.0 - 0.5 * 1.5 * 1.5);
  EXPECT_DOUBLE_EQ(h.weight(3.0), 0.5);
  EXPECT_DOUBLE_EQ(h.derivative(-10.0), -1.5);
  EXPECT_EQ(h.name(), "huber");
}

TEST(CauchyLoss, MatchesDefinition) {
  const CauchyLoss c(2.0);
  EXPECT_DOUBLE_EQ(c.loss(2.0), 2.0 * std::log(2.0));
  EXPECT_DOUBLE_EQ(c.weight(2.0), 0.5);
  EXPECT_DOUBLE_EQ(c.derivative(-2.0), -1.0);
  EXPECT_EQ(CauchyLoss().c(), 2.3849);
  EXPECT_EQ(c.name(), "cauchy");
}

TEST(SimpleLosses, InvalidParametersThrow) {
  for (double bad : {0.0, -1.0, std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_THROW(HuberLoss{bad}, std::invalid_argument);
    EXPECT_THROW(CauchyLoss{bad}, std::invalid_argument);
  }
}

// ---------------------------------------------------------------------------
// Asymmetric loss.

TEST(AsymmetricLoss, ExactlyGaussianOnTheShortSide) {
  for (Component comp : {Component::kConvolved, Component::kHalfCauchy}) {
    for (double gamma : {1.349, 20.0}) {
      const AsymmetricLoss a(gamma, 0.3, comp);
      for (double r = -1e6; r <= 0.0; r = (r < -1.0 ? r * 0.97 : r + 1e-3)) {
        ASSERT_EQ(a.loss(r), 0.5 * r * r) << "r " << r;
        ASSERT_EQ(a.derivative(r), r) << "r " << r;
        ASSERT_EQ(a.weight(r), 1.0) << "r " << r;
      }
    }
  }
}

TEST(AsymmetricLoss, LosComponentWinsForEveryNegativeResidual) {
  // The proof behind "exactly Gaussian for r <= 0": for w < 1/2, w g < (1-w) phi.
  for (double gamma : {0.01, 0.5, 5.0, 100.0}) {
    const AsymmetricLoss a(gamma, 0.49);
    for (double r : {-30.0, -12.0, -8.5}) EXPECT_GT(a.nlosLoss(r), a.losLoss(r)) << "gamma " << gamma << " r " << r;
    for (double r = AsymmetricLoss::kTableMinEps; r <= 0.0; r += 0.01) {
      ASSERT_GT(a.nlosLoss(r), a.losLoss(r)) << "gamma " << gamma << " r " << r;
    }
  }
}

TEST(AsymmetricLoss, DecisionPointSeparatesTheComponents) {
  for (Component comp : {Component::kConvolved, Component::kHalfCauchy}) {
    for (double gamma : {1.349, 5.0, 20.0}) {
      for (double w : {0.05, 0.2, 0.4}) {
        const AsymmetricLoss a(gamma, w, comp);
        const double ed = a.decisionPoint();
        ASSERT_GT(ed, 0.0);
        if (a.nlosBranchClamped()) continue;  // covered by ClampedBranchIsFlatAndMonotone
        EXPECT_NEAR(a.nlosLoss(ed), a.losLoss(ed), 1e-9);
        for (double r = 0.0; r < ed; r += ed / 50) EXPECT_EQ(a.loss(r), 0.5 * r * r);
        for (double r = ed * 1.001; r < 1e5; r *= 1.1) {
          EXPECT_LT(a.nlosLoss(r), a.losLoss(r)) << "r " << r;
          EXPECT_NEAR(a.loss(r), std::min(a.losLoss(r), a.nlosLoss(r)), 1e-12 * a.loss(r));
        }
      }
    }
  }
}

TEST(AsymmetricLoss, HeavyTailOnTheLongSide) {
  const RobustLossPtr a = makeRangeLoss("asymmetric");
  const double ed = dynamic_cast<const AsymmetricLoss&>(*a).decisionPoint();
  // Far below the Gaussian: a 10 m NLOS excess at sigma 0.15 m costs ~log, not ~r^2.
  EXPECT_LT(a->loss(10.0), 0.25 * 50.0);
  EXPECT_LT(a->loss(100.0), 0.01 * 5000.0);
  EXPECT_LT(a->weight(100.0), 1e-3);
  EXPECT_LT(a->loss(1e4), 40.0);
  // Beyond the decision point a long measurement costs less than an equally short one.
  for (double r = ed * 1.0001; r < 1e6; r *= 1.05) ASSERT_LT(a->loss(r), a->loss(-r)) << "r " << r;
  // Tail slope tends to the half-Cauchy's 2 eps / (gamma^2 + eps^2).
  const double gamma = dynamic_cast<const AsymmetricLoss&>(*a).gamma();
  for (double r : {1e3, 1e5, 1e7}) EXPECT_NEAR(a->derivative(r), 2 * r / (gamma * gamma + r * r), 1e-5 * 2 / r);
}

TEST(AsymmetricLoss, ClampedBranchIsFlatAndMonotone) {
  // Large gamma pushes the mode of g beyond the LOS/NLOS crossing.
  const AsymmetricLoss a(100.0, 0.2);
  ASSERT_TRUE(a.nlosBranchClamped());
  const double ed = a.decisionPoint();
  const double em = a.nlosMode();
  ASSERT_LT(ed, em);
  // Crossing against the clamped branch.
  EXPECT_NEAR(a.nlosLoss(em), a.losLoss(ed), 1e-9);
  for (double r = ed + 1e-6; r < em; r += (em - ed) / 40) {
    EXPECT_EQ(a.loss(r), a.loss(em));
    EXPECT_EQ(a.derivative(r), 0.0);
    EXPECT_EQ(a.weight(r), 0.0);
  }
  // Unclamped, rho_NLOS would decrease there: the clamp is what keeps rho monotone.
  EXPECT_GT(a.nlosLoss(ed) - a.nlosLoss(em), 1e-5);
  // Not clamped for the defaults.
  EXPECT_FALSE(AsymmetricLoss(1.349, 0.2).nlosBranchClamped());
}

TEST(AsymmetricLoss, NlosModeIsTheMaximumOfTheDensity) {
  for (double gamma : {0.5, 1.349, 20.0, 100.0}) {
    const AsymmetricLoss a(gamma, 0.2);
    const double em = a.nlosMode();
    EXPECT_GT(em, 0.0);
    for (double d : {-0.3, -0.01, 0.01, 0.3}) EXPECT_GT(a.nlosDensity(em), a.nlosDensity(em + d)) << gamma;
  }
}

/// Brute force: composite Simpson over c in the original variable,
/// g(eps) = int_0^inf h(c) phi(eps - c) dc, over c in [max(0, eps - 12), eps + 12].
/// Outside that window phi(eps - c) <= phi(12), and int h = 1, so the dropped
/// mass is at most 2 phi(12) (returned in *tail_bound).
double bruteForceConvolution(double gamma, double eps, double* tail_bound) {
  const double half_width = 12.0;
  const double a = std::max(0.0, eps - half_width);
  const double b = eps + half_width;
  *tail_bound = 2.0 * std::exp(-0.5 * half_width * half_width) / std::sqrt(2 * kPi);
  if (b <= 0.0) return 0.0;
  const double step = 1e-3 * std::min(1.0, gamma);
  const int n = 2 * static_cast<int>(std::ceil((b - a) / step / 2));
  const double h = (b - a) / n;
  const auto f = [&](double c) {
    return 2.0 / (kPi * gamma) / (1.0 + (c / gamma) * (c / gamma)) * std::exp(-0.5 * (eps - c) * (eps - c)) /
           std::sqrt(2 * kPi);
  };
  double sum = f(a) + f(b);
  for (int i = 1; i < n; ++i) sum += (i % 2 == 1 ? 4.0 : 2.0) * f(a + i * h);
  return sum * h / 3.0;
}

TEST(AsymmetricLoss, TabulatedConvolutionMatchesBruteForce) {
  std::vector<double> eps_values;
  for (double e = -5.0; e <= 5.0; e += 0.37) eps_values.push_back(e);
  for (double e = 5.0; e <= 1000.0; e *= 1.6) eps_values.push_back(e);
  eps_values.push_back(1000.0);
  for (double gamma : {0.5, 1.0, 5.0, 20.0}) {
    const AsymmetricLoss a(gamma, 0.2);
    for (double eps : eps_values) {
      double tail = 0.0;
      const double ref = bruteForceConvolution(gamma, eps, &tail);
      ASSERT_GT(ref, 0.0);
      ASSERT_LT(tail / ref, 1e-9) << "window too narrow at eps " << eps;
      EXPECT_NEAR(a.nlosDensity(eps) / ref, 1.0, 1e-6) << "gamma " << gamma << " eps " << eps;
    }
  }
}

TEST(AsymmetricLoss, TableAndAsymptoteMatchQuadratureEverywhere) {
  for (double gamma : {0.05, 1.349, 100.0}) {
    const AsymmetricLoss a(gamma, 0.2);
    // Off-node points over the whole table, then the asymptotic tail.
    for (double s = std::asinh(AsymmetricLoss::kTableMinEps); s < std::asinh(1e6); s += 0.0371) {
      const double eps = std::sinh(s);
      const double ref = AsymmetricLoss::convolvedDensityByQuadrature(gamma, eps);
      ASSERT_NEAR(a.nlosDensity(eps) / ref, 1.0, 1e-7) << "gamma " << gamma << " eps " << eps;
      // The interpolated slope is the true one: rho_NLOS' = -(log g)'.
      if (eps > a.decisionPoint() && eps > a.nlosMode()) {
        const double h = 1e-4 * eps;
        const double fd = -(std::log(AsymmetricLoss::convolvedDensityByQuadrature(gamma, eps + h)) -
                            std::log(AsymmetricLoss::convolvedDensityByQuadrature(gamma, eps - h))) /
                          (2 * h);
        ASSERT_NEAR(a.derivative(eps), fd, 1e-6 * std::abs(fd) + 1e-8) << "gamma " << gamma << " eps " << eps;
      }
    }
  }
}

TEST(AsymmetricLoss, HalfCauchyComponentIsThePlainDensity) {
  const AsymmetricLoss a(3.0, 0.2, Component::kHalfCauchy);
  EXPECT_EQ(a.name(), "asymmetric-half-cauchy");
  EXPECT_EQ(a.nlosMode(), 0.0);
  EXPECT_EQ(a.nlosDensity(-0.1), 0.0);
  for (double eps : {0.0, 0.5, 3.0, 40.0, 1e5}) {
    EXPECT_NEAR(a.nlosDensity(eps), 2.0 / (kPi * 3.0) / (1.0 + eps * eps / 9.0), 1e-14);
  }
}

TEST(AsymmetricLoss, HalfCauchyBarelyMovesTheDecisionPoint) {
  // Ranging-IMU Fusion paper, Fig. 2: the simpler component does not significantly change the decision point.
  for (double gamma : {1.349, 5.0, 20.0}) {
    const double conv = AsymmetricLoss(gamma, 0.2).decisionPoint();
    const double hc = AsymmetricLoss(gamma, 0.2, Component::kHalfCauchy).decisionPoint();
    EXPECT_NEAR(conv, hc, 0.15) << "gamma " << gamma;
  }
}

TEST(AsymmetricLoss, InvalidParametersThrowNamingThem) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (double gamma : {0.0, -1.0, nan, inf, 1e-4, 1e4}) {
    try {
      AsymmetricLoss a(gamma, 0.2);
      ADD_FAILURE() << "gamma " << gamma << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("gamma"), std::string::npos);
    }
  }
  for (double w : {0.0, 0.5, -0.1, 0.7, nan}) {
    try {
      AsymmetricLoss a(1.0, w);
      ADD_FAILURE() << "w " << w << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("nlos_weight"), std::string::npos);
    }
  }
  // Half-Cauchy density at 0 above the LOS one: no Gaussian core.
  EXPECT_THROW(AsymmetricLoss(0.1, 0.2, Component::kHalfCauchy), std::invalid_argument);
  EXPECT_NO_THROW(AsymmetricLoss(0.1, 0.2, Component::kConvolved));
}

// ---------------------------------------------------------------------------
// Factory.

TEST(NoiseModelFactory, NamesMapToTypes) {
  const RangeNoiseParams p;
  EXPECT_NE(dynamic_cast<const GaussianLoss*>(makeRangeLoss("gaussian", p).get()), nullptr);
  EXPECT_NE(dynamic_cast<const HuberLoss*>(makeRangeLoss("huber", p).get()), nullptr);
  EXPECT_NE(dynamic_cast<const CauchyLoss*>(makeRangeLoss("cauchy", p).get()), nullptr);
  const RobustLossPtr conv_ptr = makeRangeLoss("asymmetric", p);
  const auto* conv = dynamic_cast<const AsymmetricLoss*>(conv_ptr.get());
  ASSERT_NE(conv, nullptr);
  EXPECT_EQ(conv->component(), Component::kConvolved);
  const RobustLossPtr hc_ptr = makeRangeLoss("asymmetric-half-cauchy", p);
  const auto* hc = dynamic_cast<const AsymmetricLoss*>(hc_ptr.get());
  ASSERT_NE(hc, nullptr);
  EXPECT_EQ(hc->component(), Component::kHalfCauchy);
  for (const std::string& name : rangeLossNames()) EXPECT_EQ(makeRangeLoss(name, p)->name(), name);
}

TEST(NoiseModelFactory, ParametersReachTheLosses) {
  RangeNoiseParams p;
  p.huber_k = 2.0;
  p.cauchy_c = 3.0;
  p.sigma_m = 0.1;
  p.nlos_weight = 0.3;
  EXPECT_EQ(dynamic_cast<const HuberLoss&>(*makeRangeLoss("huber", p)).k(), 2.0);
  EXPECT_EQ(dynamic_cast<const CauchyLoss&>(*makeRangeLoss("cauchy", p)).c(), 3.0);
  // Default NLOS scale: IQR of N(0, sigma) -> whitened gamma = 1.349 for any sigma.
  const RobustLossPtr def = makeRangeLoss("asymmetric", p);
  EXPECT_NEAR(dynamic_cast<const AsymmetricLoss&>(*def).gamma(), 1.3489795003921634, 1e-12);
  EXPECT_EQ(dynamic_cast<const AsymmetricLoss&>(*def).nlosWeight(), 0.3);
  p.nlos_scale_m = 0.5;
  const RobustLossPtr set = makeRangeLoss("asymmetric-half-cauchy", p);
  EXPECT_NEAR(dynamic_cast<const AsymmetricLoss&>(*set).gamma(), 5.0, 1e-12);
}

TEST(NoiseModelFactory, UnknownNameListsValidNames) {
  try {
    makeRangeLoss("tukey", RangeNoiseParams{});
    FAIL() << "unknown name accepted";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("tukey"), std::string::npos);
    for (const std::string& name : rangeLossNames()) EXPECT_NE(msg.find(name), std::string::npos) << msg;
  }
}

TEST(NoiseModelFactory, InvalidParametersThrowNamingThem) {
  RangeNoiseParams p;
  p.sigma_m = 0.0;
  try {
    makeRangeLoss("asymmetric", p);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("sigma_m"), std::string::npos);
  }
  p = RangeNoiseParams{};
  p.nlos_scale_m = -0.2;
  EXPECT_THROW(makeRangeLoss("asymmetric", p), std::invalid_argument);
  p = RangeNoiseParams{};
  p.nlos_weight = 0.6;
  EXPECT_THROW(makeRangeLoss("asymmetric", p), std::invalid_argument);
  p = RangeNoiseParams{};
  p.huber_k = -1.0;
  EXPECT_THROW(makeRangeLoss("huber", p), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
