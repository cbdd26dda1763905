// RxLevelEnvelope: fits the LOS path-loss line under an NLOS majority, puts
// LOS ranges near zero deficit and attenuated ones well above the flag
// threshold, falls back to free space without spread of distance, keeps the
// exponent in its bounds, ignores malformed input, says nothing before
// min_ranges, and does not allocate.
#include "estimation/measurements/rx_level_envelope.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "support/new_counter.h"

namespace rilo {
namespace {

// A site: LOS level a - 10 n log10(r) with fading N(0, fade_db); a share
// nlos_share of the ranges attenuated by a further loss uniform in
// [loss_lo_db, loss_hi_db]; ranges uniform in [r_lo, r_hi] m.
struct Site {
  double a_dbm = -42.0, n = 2.0, fade_db = 1.5;
  double nlos_share = 0.7, loss_lo_db = 6.0, loss_hi_db = 14.0;
  double r_lo = 2.0, r_hi = 30.0;
};

struct Ranged {
  double range_m, rssi_dbm;
  bool nlos;
};

Ranged draw(const Site& s, std::mt19937& rng) {
  std::uniform_real_distribution<double> r(s.r_lo, s.r_hi), u(0.0, 1.0), loss(s.loss_lo_db, s.loss_hi_db);
  std::normal_distribution<double> fade(0.0, s.fade_db);
  const double d = r(rng);
  const bool nlos = u(rng) < s.nlos_share;
  return {d, s.a_dbm - 10.0 * s.n * std::log10(d) + fade(rng) - (nlos ? loss(rng) : 0.0), nlos};
}

/// n ranges of the site into env.
void learn(RxLevelEnvelope& env, const Site& site, int n, std::mt19937& rng) {
  for (int i = 0; i < n; ++i) {
    const Ranged x = draw(site, rng);
    env.add(x.range_m, x.rssi_dbm);
  }
}

TEST(RxLevelEnvelope, SeparatesAttenuatedRangesUnderAnNlosMajority) {
  const Site site;
  RxLevelEnvelope env;
  std::mt19937 rng(3);
  learn(env, site, 3000, rng);
  ASSERT_TRUE(env.fitted());
  EXPECT_NEAR(env.exponent(), site.n, 0.5);
  // At mid-range, what the deficit rests on: below the true LOS level, never
  // far above it (with 70 % NLOS the upper half holds attenuated ranges,
  // which flags fewer of them).
  const double los_10m_dbm = site.a_dbm - 10.0 * site.n;
  EXPECT_LT(env.losLevelDbm(10.0), los_10m_dbm + 1.0);
  EXPECT_GT(env.losLevelDbm(10.0), los_10m_dbm - 4.0);
  int los = 0, los_low = 0, nlos = 0, nlos_flagged = 0;
  for (int i = 0; i < 4000; ++i) {
    const Ranged x = draw(site, rng);
    const double d = env.deficitDb(x.range_m, x.rssi_dbm);
    ASSERT_GE(d, 0.0);
    if (x.nlos) {
      ++nlos;
      nlos_flagged += d > 6.0 ? 1 : 0;
    } else {
      ++los;
      los_low += d < 3.0 ? 1 : 0;
    }
  }
  EXPECT_GT(static_cast<double>(los_low) / los, 0.9);
  EXPECT_GT(static_cast<double>(nlos_flagged) / nlos, 0.6);
}

TEST(RxLevelEnvelope, MostlyLosSiteKeepsLosRangesBelowTheFlag) {
  Site site;
  site.nlos_share = 0.1;
  RxLevelEnvelope env;
  std::mt19937 rng(5);
  learn(env, site, 3000, rng);
  int los = 0, los_flagged = 0;
  for (int i = 0; i < 4000; ++i) {
    const Ranged x = draw(site, rng);
    if (x.nlos) continue;
    ++los;
    los_flagged += env.deficitDb(x.range_m, x.rssi_dbm) > 6.0 ? 1 : 0;
  }
  EXPECT_LT(static_cast<double>(los_flagged) / los, 0.02);
}

TEST(RxLevelEnvelope, NothingBeforeMinRanges) {
  RxLevelEnvelopeParams p;
  p.min_ranges = 50;
  RxLevelEnvelope env(p);
  std::mt19937 rng(1);
  const Site site;
  learn(env, site, 49, rng);
  EXPECT_FALSE(env.fitted());
  EXPECT_TRUE(std::isnan(env.deficitDb(5.0, -70.0)));
  EXPECT_TRUE(std::isnan(env.exponent()));
  EXPECT_TRUE(std::isnan(env.losLevelDbm(10.0)));
  env.add(5.0, -60.0);
  EXPECT_TRUE(env.fitted());
  env.reset();
  EXPECT_FALSE(env.fitted());
}

TEST(RxLevelEnvelope, FreeSpaceWithoutSpreadOfDistance) {
  Site site;
  site.r_lo = 9.9;
  site.r_hi = 10.1;
  site.n = 3.5;  // not observable from one distance: free space is assumed
  RxLevelEnvelope env;
  std::mt19937 rng(2);
  learn(env, site, 500, rng);
  ASSERT_TRUE(env.fitted());
  EXPECT_DOUBLE_EQ(env.exponent(), 2.0);
}

TEST(RxLevelEnvelope, ExponentStaysInItsBounds) {
  Site site;
  site.n = 6.0;
  site.nlos_share = 0.0;
  RxLevelEnvelope env;
  std::mt19937 rng(4);
  learn(env, site, 1000, rng);
  EXPECT_NEAR(env.exponent(), RxLevelEnvelopeParams().max_exponent, 1e-9);
}

TEST(RxLevelEnvelope, IgnoresMalformedInputAndDisabled) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  RxLevelEnvelopeParams p;
  p.min_ranges = 8;
  RxLevelEnvelope env(p);
  for (int i = 0; i < 100; ++i) {
    env.add(nan, -60.0);
    env.add(5.0, nan);
    env.add(inf, -60.0);
    env.add(5.0, -inf);
    env.add(5.0, 1e300);  // finite, not a signal level: would overflow the sums
    env.add(-5.0, -60.0);
    env.add(5.0, 12.0);
  }
  EXPECT_FALSE(env.fitted());
  // Free space clamped to the bounds when the distance does not spread.
  p.min_exponent = 2.5;
  RxLevelEnvelope narrow(p);
  for (int i = 0; i < 20; ++i) narrow.add(10.0, -62.0 - 0.1 * i);
  ASSERT_TRUE(narrow.fitted());
  EXPECT_DOUBLE_EQ(narrow.exponent(), 2.5);
  p.min_exponent = RxLevelEnvelopeParams().min_exponent;
  p.enabled = false;
  RxLevelEnvelope off(p);
  for (int i = 0; i < 100; ++i) off.add(1.0 + i, -50.0 - i);
  EXPECT_FALSE(off.fitted());
}

TEST(RxLevelEnvelope, RejectsMalformedParameters) {
  auto bad = [](RxLevelEnvelopeParams p, const char* field) {
    try {
      RxLevelEnvelope env(p);
      ADD_FAILURE() << "accepted " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  RxLevelEnvelopeParams p;
  p.window_ranges = RxLevelEnvelope::kCapacity + 1;
  bad(p, "window_ranges");
  p = {};
  p.min_ranges = p.window_ranges + 1;
  bad(p, "min_ranges");
  p = {};
  p.refit_every = 0;
  bad(p, "refit_every");
  p = {};
  p.fit_iterations = 0;
  bad(p, "fit_iterations");
  p = {};
  p.min_log10_span = std::numeric_limits<double>::quiet_NaN();
  bad(p, "min_log10_span");
  p = {};
  p.max_exponent = 1.0;
  bad(p, "min_exponent");
}

TEST(RxLevelEnvelope, AddingNeverAllocates) {
  RxLevelEnvelope env;
  std::mt19937 rng(6);
  const Site site;
  std::uint64_t news = 0;
  {
    testing::NewCounter counter;
    learn(env, site, 5000, rng);
    news = counter.count();
  }
  EXPECT_EQ(news, 0u);
  EXPECT_TRUE(env.fitted());
}

}  // namespace
}  // namespace rilo
