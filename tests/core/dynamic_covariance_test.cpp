// Dynamic covariance (the IMU-Ultrasonic-UWB paper's "dynamic covariance estimation"): the
// per-link robust scale converges to the residuals' sigma, follows a
// persistent change both ways, shrugs off a short burst of outliers, stays in
// its bounds, keeps keys apart and reports a full table.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "estimation/noise/dynamic_covariance.h"
#include "support/expect_throws_naming.h"

namespace rilo {
namespace {

using rilo::testing::expectThrowsNaming;

DynamicCovarianceParams defaults() { return DynamicCovarianceParams{}; }

TEST(DynamicCovariance, ConsistencyFactorIsTheClippedSecondMoment) {
  // Monte Carlo of E[min(Z^2, c^2)].
  std::mt19937_64 rng(1);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (double c : {1.0, 2.0, 3.0}) {
    double sum = 0.0;
    const int n = 400000;
    for (int i = 0; i < n; ++i) {
      const double z = n01(rng);
      sum += std::min(z * z, c * c);
    }
    EXPECT_NEAR(DynamicCovariance::consistency(c), sum / n, 0.01) << "c = " << c;
  }
  EXPECT_NEAR(DynamicCovariance::consistency(50.0), 1.0, 1e-12);
}

TEST(DynamicCovariance, ConvergesToTheTrueSigmaOfGaussianResiduals) {
  DynamicCovariance dc(defaults());
  std::mt19937_64 rng(2);
  std::normal_distribution<double> n01(0.0, 1.0);
  // Eight TDoA pairs with different true sigmas, interleaved as they arrive.
  const std::vector<double> truth = {0.06, 0.1, 0.15, 0.2, 0.3, 0.45, 0.7, 1.0};
  std::vector<double> sum(truth.size(), 0.0);
  std::vector<double> worst(truth.size(), 0.0);
  int averaged = 0;
  for (int k = 0; k < 6000; ++k) {
    for (std::size_t j = 0; j < truth.size(); ++j) {
      const NoiseKey key = NoiseKey::tdoa(static_cast<std::uint32_t>(j), static_cast<std::uint32_t>(j + 1));
      dc.update(key, truth[j] * n01(rng));
      if (k >= 1000) {
        const double rel = dc.sigma(key) / truth[j] - 1.0;
        sum[j] += dc.sigma(key);
        worst[j] = std::max(worst[j], std::abs(rel));
      }
    }
    if (k >= 1000) ++averaged;
  }
  for (std::size_t j = 0; j < truth.size(); ++j) {
    const double mean = sum[j] / averaged;
    std::printf("[ info ] true sigma %.2f m: mean estimate %.4f m (%.1f%%), worst %.1f%% over 5000 samples\n",
                truth[j], mean, 100.0 * (mean / truth[j] - 1.0), 100.0 * worst[j]);
    EXPECT_NEAR(mean / truth[j], 1.0, 0.03) << "sigma " << truth[j];
    EXPECT_LT(worst[j], 0.25) << "sigma " << truth[j];
  }
}

TEST(DynamicCovariance, RisesWhenTheNoiseDoublesAndComesBack) {
  DynamicCovarianceParams p = defaults();
  DynamicCovariance dc(p);
  const NoiseKey key = NoiseKey::range(3);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  auto feed = [&](double sigma, int n) {
    for (int i = 0; i < n; ++i) dc.update(key, sigma * n01(rng));
  };
  feed(0.1, 1000);
  EXPECT_NEAR(dc.sigma(key), 0.1, 0.015);
  feed(0.2, static_cast<int>(0.5 * p.window_samples));
  const double half_window = dc.sigma(key);
  feed(0.2, static_cast<int>(2.5 * p.window_samples));
  const double risen = dc.sigma(key);
  feed(0.1, static_cast<int>(1.0 * p.window_samples));
  const double one_window_back = dc.sigma(key);
  feed(0.1, static_cast<int>(4.0 * p.window_samples));
  const double back = dc.sigma(key);
  std::printf(
      "[ info ] 0.1 -> 0.2 m: %.3f after 0.5 window, %.3f after 3; back to 0.1: %.3f after 1 window, %.3f after 5\n",
      half_window, risen, one_window_back, back);
  EXPECT_GT(half_window, 0.125);  // on its way within half a window
  EXPECT_NEAR(risen, 0.2, 0.03);
  EXPECT_LT(one_window_back, 0.17);
  EXPECT_NEAR(back, 0.1, 0.015);
}

TEST(DynamicCovariance, ShortBurstOfOutliersMovesItLittle) {
  DynamicCovariance dc(defaults());
  const NoiseKey key = NoiseKey::tdoa(2, 5);
  std::mt19937_64 rng(4);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int i = 0; i < 1000; ++i) dc.update(key, 0.1 * n01(rng));
  const double before = dc.sigma(key);
  for (int i = 0; i < 5; ++i) dc.update(key, i % 2 ? 5.0 : -5.0);  // NLOS burst / multipath, either sign
  const double after = dc.sigma(key);
  std::printf("[ info ] 5 outliers of 5 m at sigma 0.1 m: %.4f -> %.4f m (+%.1f%%)\n", before, after,
              100.0 * (after / before - 1.0));
  EXPECT_LT(after / before, 1.12);  // bound: (1 + lambda (c^2 / beta - 1))^(5/2) = 1.086
  for (int i = 0; i < 500; ++i) dc.update(key, 0.1 * n01(rng));
  EXPECT_NEAR(dc.sigma(key), 0.1, 0.015);

  // A persistent NLOS bias is not a burst: the second moment about zero
  // grows, the link loses weight.
  for (int i = 0; i < 1000; ++i) dc.update(key, 0.5 + 0.1 * n01(rng));
  EXPECT_NEAR(dc.sigma(key), std::sqrt(0.5 * 0.5 + 0.1 * 0.1), 0.05);
}

TEST(DynamicCovariance, BoundsAreRespected) {
  DynamicCovarianceParams p = defaults();
  DynamicCovariance dc(p);
  const NoiseKey loud = NoiseKey::ultrasonic(1), quiet = NoiseKey::ultrasonic(2);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int i = 0; i < 3000; ++i) {
    dc.update(loud, 10.0 * n01(rng));
    dc.update(quiet, 1e-6 * n01(rng));
    ASSERT_LE(dc.sigma(loud), p.ultrasonic.sigma_max_m);
    ASSERT_GE(dc.sigma(quiet), p.ultrasonic.sigma_min_m);
  }
  EXPECT_DOUBLE_EQ(dc.sigma(loud), p.ultrasonic.sigma_max_m);
  EXPECT_DOUBLE_EQ(dc.sigma(quiet), p.ultrasonic.sigma_min_m);
  EXPECT_DOUBLE_EQ(dc.scale(loud), p.ultrasonic.sigma_max_m / p.ultrasonic.nominal_sigma_m);
  // Exactly zero residuals (a stuck source): the lower bound, not zero.
  const NoiseKey stuck = NoiseKey::range(9);
  for (int i = 0; i < 100; ++i) dc.update(stuck, 0.0);
  EXPECT_DOUBLE_EQ(dc.sigma(stuck), p.range.sigma_min_m);
}

TEST(DynamicCovariance, NominalUntilTheWarmUpIsOverThenTheRobustStart) {
  DynamicCovarianceParams p = defaults();
  p.min_samples = 10;
  DynamicCovariance dc(p);
  const NoiseKey key = NoiseKey::range(0);
  EXPECT_FALSE(dc.tracked(key));
  EXPECT_DOUBLE_EQ(dc.sigma(key), p.range.nominal_sigma_m);
  // Half a metre of noise, 3 of 10 warm-up residuals NLOS outliers.
  const std::vector<double> r = {0.4, -0.6, 8.0, 0.5, -0.45, 9.0, 0.55, -0.5, 7.0, 0.3};
  for (std::size_t i = 0; i + 1 < r.size(); ++i) {
    EXPECT_EQ(dc.update(key, r[i]), CovarianceUpdate::kWarmingUp);
    EXPECT_DOUBLE_EQ(dc.sigma(key), p.range.nominal_sigma_m);
    EXPECT_FALSE(dc.estimated(key));
  }
  EXPECT_EQ(dc.update(key, r.back()), CovarianceUpdate::kUpdated);
  EXPECT_TRUE(dc.estimated(key));
  EXPECT_EQ(dc.samples(key), 10);
  // Median |r| = (0.5 + 0.55) / 2 -> 1.4826 * 0.525 = 0.778 m; the outliers did not take over.
  EXPECT_NEAR(dc.sigma(key), 1.482602218505602 * 0.525, 1e-9);
}

TEST(DynamicCovariance, InnovationsWithPredictedVarianceGiveTheMeasurementSigma) {
  DynamicCovariance dc(defaults());
  const NoiseKey key = NoiseKey::range(4);
  std::mt19937_64 rng(6);
  std::normal_distribution<double> n01(0.0, 1.0);
  const double sigma = 0.12, predicted_var = 0.04;  // the state's share is larger than the noise
  double sum = 0.0;
  for (int i = 0; i < 6000; ++i) {
    dc.update(key, std::sqrt(sigma * sigma + predicted_var) * n01(rng), predicted_var);
    if (i >= 1000) sum += dc.sigma(key);
  }
  EXPECT_NEAR(sum / 5000.0, sigma, 0.1 * sigma);
}

TEST(DynamicCovariance, KeysAreSeparateAndTdoaPairsUnordered) {
  DynamicCovariance dc(defaults());
  EXPECT_EQ(NoiseKey::tdoa(3, 1), NoiseKey::tdoa(1, 3));
  EXPECT_FALSE(NoiseKey::range(1) == NoiseKey::ultrasonic(1));
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    // The same pair in both orders: the sign flips, the spread is the pair's.
    dc.update(i % 2 ? NoiseKey::tdoa(1, 3) : NoiseKey::tdoa(3, 1), 0.3 * n01(rng));
    dc.update(NoiseKey::range(1), 0.05 * n01(rng));
    dc.update(NoiseKey::ultrasonic(1), 0.01 * n01(rng));
  }
  EXPECT_EQ(dc.size(), 3);
  EXPECT_EQ(dc.samples(NoiseKey::tdoa(1, 3)), 2000);
  EXPECT_NEAR(dc.sigma(NoiseKey::tdoa(3, 1)), 0.3, 0.045);
  EXPECT_NEAR(dc.sigma(NoiseKey::range(1)), 0.05, 0.0075);
  EXPECT_NEAR(dc.sigma(NoiseKey::ultrasonic(1)), 0.01, 0.0015);
  EXPECT_DOUBLE_EQ(dc.sigma(NoiseKey::tdoa(1, 2)), dc.params().tdoa.nominal_sigma_m);  // never seen
}

TEST(DynamicCovariance, FullTableIsReportedAndKnownKeysKeepWorking) {
  DynamicCovarianceParams p = defaults();
  p.max_keys = 3;
  DynamicCovariance dc(p);
  for (std::uint32_t id = 0; id < 3; ++id) EXPECT_EQ(dc.update(NoiseKey::range(id), 0.1), CovarianceUpdate::kWarmingUp);
  EXPECT_EQ(dc.update(NoiseKey::range(7), 0.1), CovarianceUpdate::kTableFull);
  EXPECT_EQ(dc.update(NoiseKey::tdoa(0, 1), 0.1), CovarianceUpdate::kTableFull);
  EXPECT_EQ(dc.dropped(), 2u);
  EXPECT_FALSE(dc.tracked(NoiseKey::range(7)));
  EXPECT_DOUBLE_EQ(dc.sigma(NoiseKey::range(7)), p.range.nominal_sigma_m);
  EXPECT_EQ(dc.samples(NoiseKey::range(7)), 0);
  EXPECT_EQ(dc.size(), 3);
  EXPECT_EQ(dc.capacity(), 3);
  for (int i = 0; i < 100; ++i) EXPECT_NE(dc.update(NoiseKey::range(1), 0.3), CovarianceUpdate::kTableFull);
  EXPECT_TRUE(dc.estimated(NoiseKey::range(1)));

  dc.reset();
  EXPECT_EQ(dc.size(), 0);
  EXPECT_EQ(dc.dropped(), 0u);
  EXPECT_FALSE(dc.tracked(NoiseKey::range(1)));
  EXPECT_EQ(dc.update(NoiseKey::range(7), 0.1), CovarianceUpdate::kWarmingUp);
}

TEST(DynamicCovariance, ManyKeysUpToCapacity) {
  DynamicCovarianceParams p = defaults();
  p.max_keys = 200;
  DynamicCovariance dc(p);
  // All TDoA pairs of 20 anchors (190 keys): every one found again after insertion.
  std::uint32_t count = 0;
  for (std::uint32_t a = 0; a < 20; ++a) {
    for (std::uint32_t b = a + 1; b < 20; ++b) {
      ASSERT_EQ(dc.update(NoiseKey::tdoa(a, b), 0.01 * (a + 1)), CovarianceUpdate::kWarmingUp);
      ++count;
    }
  }
  EXPECT_EQ(dc.size(), static_cast<int>(count));
  for (std::uint32_t a = 0; a < 20; ++a) {
    for (std::uint32_t b = a + 1; b < 20; ++b) ASSERT_EQ(dc.samples(NoiseKey::tdoa(b, a)), 1);
  }
}

TEST(DynamicCovariance, NonFiniteResidualsAreRejected) {
  DynamicCovariance dc(defaults());
  const NoiseKey key = NoiseKey::range(0);
  for (int i = 0; i < 50; ++i) dc.update(key, i % 2 ? 0.1 : -0.1);
  const double before = dc.sigma(key);
  EXPECT_EQ(dc.update(key, std::nan("")), CovarianceUpdate::kRejectedNonFinite);
  EXPECT_EQ(dc.update(key, INFINITY), CovarianceUpdate::kRejectedNonFinite);
  EXPECT_EQ(dc.update(key, 0.1, -1.0), CovarianceUpdate::kRejectedNonFinite);
  EXPECT_EQ(dc.update(key, 0.1, std::nan("")), CovarianceUpdate::kRejectedNonFinite);
  EXPECT_DOUBLE_EQ(dc.sigma(key), before);
  EXPECT_EQ(dc.samples(key), 50);
}

TEST(DynamicCovariance, InvalidParamsThrowNamingTheField) {
  auto check = [](auto edit, const std::string& field) {
    DynamicCovarianceParams p;
    edit(p);
    expectThrowsNaming([&] { p.validate(); }, "DynamicCovarianceParams." + field);
    expectThrowsNaming([&] { DynamicCovariance dc(p); }, "DynamicCovarianceParams." + field);
  };
  check([](DynamicCovarianceParams& p) { p.max_keys = 0; }, "max_keys");
  check([](DynamicCovarianceParams& p) { p.window_samples = 1.0; }, "window_samples");
  check([](DynamicCovarianceParams& p) { p.window_samples = NAN; }, "window_samples");
  check([](DynamicCovarianceParams& p) { p.min_samples = 2; }, "min_samples");
  check([](DynamicCovarianceParams& p) { p.min_samples = DynamicCovariance::kMaxWarmupSamples + 1; }, "min_samples");
  check([](DynamicCovarianceParams& p) { p.huber_c = 0.0; }, "huber_c");
  check([](DynamicCovarianceParams& p) { p.range.sigma_min_m = 0.0; }, "range.sigma_min_m");
  check([](DynamicCovarianceParams& p) { p.tdoa.sigma_max_m = 0.01; }, "tdoa.sigma_max_m");
  check([](DynamicCovarianceParams& p) { p.ultrasonic.nominal_sigma_m = 1.0; }, "ultrasonic.nominal_sigma_m");
  check([](DynamicCovarianceParams& p) { p.tdoa.sigma_max_m = INFINITY; }, "tdoa.sigma_max_m");
}

}  // namespace
}  // namespace rilo
