// LosGapCalibrator: finds where the LOS gaps end from residuals by gap, keeps
// the configured threshold without evidence, never goes below min_gap_db or
// (for the receiver's own gaps) above the configured value, rises for gaps
// from the RX level only through bins that showed LOS, needs two bins in a
// row for a step, cancels a common residual shift, ignores malformed input,
// and does not allocate.
#include "estimation/measurements/los_gap_calibration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "support/new_counter.h"

namespace rilo {
namespace {

constexpr double kSigma = 0.15;

// Residuals of a site: LOS (N(0, sigma) + shift) below `los_top_db`, NLOS
// above it (excess uniform in [0.1, 0.5] m + shift), gaps uniform in [1, 9) dB.
// from_rx_level: the gaps stand in from the RX level (and reach 12 dB).
void feed(LosGapCalibrator& c, double los_top_db, int n, double shift_m = 0.0, unsigned seed = 1,
          bool from_rx_level = false) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> gap(1.0, from_rx_level ? 12.0 : 9.0), excess(0.1, 0.5);
  std::normal_distribution<double> noise(0.0, kSigma);
  for (int i = 0; i < n; ++i) {
    const double g = gap(rng);
    c.add(g, shift_m + noise(rng) + (g >= los_top_db ? excess(rng) : 0.0), from_rx_level);
  }
}

// n ranges with gaps uniform in [1, gap_hi_db) and LOS noise plus
// excess_of(gap) (m; NaN: the gap is never heard).
template <class Excess>
void feedSite(LosGapCalibrator& c, int n, double gap_hi_db, unsigned seed, bool from_rx_level, Excess excess_of) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> gap(1.0, gap_hi_db);
  std::normal_distribution<double> noise(0.0, kSigma);
  for (int i = 0; i < n; ++i) {
    const double g = gap(rng);
    const double excess_m = excess_of(g);
    if (!std::isnan(excess_m)) c.add(g, noise(rng) + excess_m, from_rx_level);
  }
}

TEST(LosGapCalibrator, FindsWhereTheLosGapsEnd) {
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  EXPECT_EQ(c.threshold(), 6.0);
  feed(c, 4.5, 4000);
  EXPECT_EQ(c.threshold(), 4.5);
  EXPECT_NEAR(c.reference(), 0.0, 0.03);
}

TEST(LosGapCalibrator, ACommonShiftCancels) {
  // A pose bias moves every residual alike: the step is still found.
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  feed(c, 4.0, 4000, -0.12);
  EXPECT_EQ(c.threshold(), 4.0);
  EXPECT_NEAR(c.reference(), -0.12, 0.03);
}

TEST(LosGapCalibrator, MeasuresEachBinsExcessOverTheReference) {
  // Excess growing with the gap above 4 dB: 0.1 m per dB, under a common
  // shift that the reference takes out.
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  EXPECT_TRUE(std::isnan(c.excessTable().at(5.0))) << "nothing known before the data";
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> gap(1.0, 6.0);
  std::normal_distribution<double> noise(0.0, kSigma);
  for (int i = 0; i < 8000; ++i) {
    const double g = gap(rng);
    c.add(g, -0.1 + noise(rng) + (g > 4.0 ? 0.1 * (g - 4.0) + 0.1 : 0.0));
  }
  const GapExcessTable& t = c.excessTable();
  EXPECT_TRUE(std::isnan(t.at(2.0))) << "the reference bins have none";
  EXPECT_NEAR(t.at(3.2), 0.0, 0.04);
  EXPECT_NEAR(t.at(4.2), 0.125, 0.04);
  EXPECT_NEAR(t.at(5.7), 0.275, 0.04);
  EXPECT_GT(t.at(5.7), t.at(4.2));
  EXPECT_TRUE(std::isnan(t.at(6.5))) << "above the configured threshold the site's excess applies";
  EXPECT_TRUE(std::isnan(t.at(std::numeric_limits<double>::quiet_NaN())));
  EXPECT_TRUE(std::isnan(t.at(1e300)));
  EXPECT_TRUE(std::isnan(t.at(-1.0)));
  for (double e : t.excess_m) EXPECT_TRUE(std::isnan(e) || e >= 0.0) << "never a negative shift";
  c.reset();
  EXPECT_TRUE(std::isnan(c.excessTable().at(5.7)));
}

TEST(LosGapCalibrator, KeepsTheConfiguredThresholdWhereEverythingBelowIsLos) {
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  feed(c, 7.0, 4000);  // the receiver's LOS gaps reach past the configured 6 dB
  EXPECT_EQ(c.threshold(), 6.0);
}

TEST(LosGapCalibrator, GapsFromTheRxLevelRaiseItUpToTheirOwnBound) {
  // The RX-level stand-in's scale is the envelope's, not the vendor's: where
  // its LOS reaches past 6 dB (a LOS-majority hall), the threshold follows.
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  feed(c, 7.5, 6000, 0.0, 1, true);
  EXPECT_EQ(c.threshold(), 7.5);
  // The excess table stays below the configured threshold (above it: the mode).
  EXPECT_TRUE(std::isnan(c.excessTable().at(6.25)));
  EXPECT_FALSE(std::isnan(c.excessTable().at(5.75)));
  // Never past rx_level_max_gap_db (9 dB), however far the LOS reaches;
  // beyond the bins (16 dB) it is clamped to them.
  LosGapCalibrator far(LosGapParams(), kSigma, 6.0);
  feed(far, 11.0, 6000, 0.0, 1, true);
  EXPECT_EQ(far.threshold(), 9.0);
  LosGapParams unbounded;
  unbounded.rx_level_max_gap_db = std::numeric_limits<double>::infinity();
  LosGapCalibrator clamped(unbounded, kSigma, 6.0);
  feedSite(clamped, 20000, 17.0, 8, true, [](double) { return 0.0; });
  EXPECT_EQ(clamped.threshold(), LosGapCalibrator::kBins * unbounded.bin_db);
  // Below the configured threshold they lower it as the receiver's gaps do.
  LosGapCalibrator low(LosGapParams(), kSigma, 6.0);
  feed(low, 4.5, 6000, 0.0, 1, true);
  EXPECT_EQ(low.threshold(), 4.5);
}

TEST(LosGapCalibrator, AnyReceiverGapKeepsTheConfiguredBound) {
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  feed(c, 7.5, 6000, 0.0, 1, true);
  ASSERT_EQ(c.threshold(), 7.5);
  // One receiver gap above every bin (not binned): the receiver's flags share
  // the threshold, so the vendor's bound is back.
  c.add(14.0, 0.0);
  for (int i = 0; i < LosGapParams().recompute_every; ++i) c.add(2.5, 0.0, true);
  EXPECT_EQ(c.threshold(), 6.0);
  // kBins * kPerBin RX-level ranges later it is forgotten: the raise returns.
  feed(c, 7.5, LosGapCalibrator::kBins * LosGapCalibrator::kPerBin + 400, 0.0, 2, true);
  EXPECT_EQ(c.threshold(), 7.5);
  // reset() forgets it too.
  c.add(2.0, 0.0);
  c.reset();
  feed(c, 7.5, 6000, 0.0, 3, true);
  EXPECT_EQ(c.threshold(), 7.5);
  // The receiver's own gaps never raise it, however far their LOS reaches.
  LosGapCalibrator rx(LosGapParams(), kSigma, 6.0);
  feed(rx, 7.5, 6000);
  EXPECT_EQ(rx.threshold(), 6.0);
}

TEST(LosGapCalibrator, ABinWithExcessPastTheConfiguredThresholdStopsTheRise) {
  // (7.0, 7.5] alone long, LOS after it: above the configured value a rise
  // stops where excess shows, confirmed or not.
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  feedSite(c, 6000, 12.0, 5, true, [](double g) { return g > 7.0 && g <= 7.5 ? 0.3 : (g > 10.0 ? 0.3 : 0.0); });
  EXPECT_EQ(c.threshold(), 7.0);
  // A configured threshold between bin edges: the bin that reaches past it
  // needs evidence too (unfilled: the rise stops at the configured value).
  LosGapCalibrator off_edge(LosGapParams(), kSigma, 6.2);
  feedSite(off_edge, 6000, 12.0, 6, true, [](double g) {
    return g > 6.0 && g <= 6.5 ? std::numeric_limits<double>::quiet_NaN() : (g > 9.0 ? 0.3 : 0.0);
  });
  EXPECT_EQ(off_edge.threshold(), 6.2);
  // A step waiting for confirmation when the next bin past the configured
  // value is unfilled: it stands alone.
  LosGapCalibrator waiting(LosGapParams(), kSigma, 6.0);
  feedSite(waiting, 6000, 12.0, 7, true, [](double g) {
    return g > 6.0 && g <= 6.5 ? std::numeric_limits<double>::quiet_NaN() : (g > 5.5 ? 0.3 : 0.0);
  });
  EXPECT_EQ(waiting.threshold(), 5.5);
}

TEST(LosGapCalibrator, RisesOnlyThroughBinsThatShowedTheyAreLos) {
  // LOS up to 9 dB, but nothing heard between 7 and 8 dB: no evidence past 7.
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  feedSite(c, 6000, 12.0, 3, true, [](double g) {
    return g > 7.0 && g <= 8.0 ? std::numeric_limits<double>::quiet_NaN() : (g > 9.0 ? 0.3 : 0.0);
  });
  EXPECT_EQ(c.threshold(), 7.0);
  // Without a reference the configured threshold, whatever the gaps' kind.
  LosGapCalibrator none(LosGapParams(), kSigma, 6.0);
  for (int i = 0; i < 1000; ++i) none.add(7.0 + 0.001 * i, 0.0, true);
  EXPECT_EQ(none.threshold(), 6.0);
}

TEST(LosGapCalibrator, OneBinAloneIsNoStep) {
  // One bin's median crossing the step, its neighbours LOS (a tracked-pose
  // error projected on the anchors that bin happens to hold): no step. Two
  // bins in a row: the step at the first.
  auto site = [](double lone_lo_db, double step_lo_db) {
    LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
    feedSite(c, 6000, 6.0, 4, false, [&](double g) {
      const bool lone = g > lone_lo_db && g <= lone_lo_db + 0.5;
      return lone || g > step_lo_db ? 0.3 : 0.0;
    });
    return c.threshold();
  };
  EXPECT_EQ(site(3.5, 100.0), 6.0);
  EXPECT_EQ(site(3.5, 4.5), 4.5);
  EXPECT_EQ(site(100.0, 4.0), 4.0);
  // The last bin below the bound has none after it: it stands alone.
  EXPECT_EQ(site(5.5, 100.0), 5.5);
}

TEST(LosGapCalibrator, NeverBelowTheFloorNorAboveTheConfiguredValue) {
  LosGapParams p;
  p.min_gap_db = 3.0;
  LosGapCalibrator c(p, kSigma, 6.0);
  feed(c, 2.0, 4000);  // the reference itself holds NLOS ranges above 2 dB
  EXPECT_GE(c.threshold(), 3.0);
  LosGapCalibrator low(p, kSigma, 5.0);
  feed(low, 5.5, 4000);
  EXPECT_EQ(low.threshold(), 5.0);
}

TEST(LosGapCalibrator, NeedsAReferenceAndEnoughRangesPerBin) {
  LosGapParams p;
  p.reference_ranges = 100;
  LosGapCalibrator c(p, kSigma, 6.0);
  // Only NLOS-looking ranges above 3 dB: no reference, no change.
  for (int i = 0; i < 2000; ++i) c.add(3.0 + 3.0 * (i % 100) / 100.0, 0.4);
  EXPECT_EQ(c.threshold(), 6.0);
  EXPECT_TRUE(std::isnan(c.reference()));
  // A reference, but the stepped bin has fewer than min_bin_ranges ranges.
  LosGapCalibrator sparse(p, kSigma, 6.0);
  for (int i = 0; i < 200; ++i) sparse.add(2.0, 0.0);
  for (int i = 0; i < p.min_bin_ranges - 1; ++i) sparse.add(4.2, 0.5);
  for (int i = 0; i < 40; ++i) sparse.add(2.5, 0.0);  // triggers a recomputation
  EXPECT_EQ(sparse.threshold(), 6.0);
  for (int i = 0; i < 2; ++i) sparse.add(4.2, 0.5);
  for (int i = 0; i < 40; ++i) sparse.add(2.5, 0.0);
  EXPECT_EQ(sparse.threshold(), 4.0);
}

TEST(LosGapCalibrator, IgnoresMalformedInputAndResets) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  for (int i = 0; i < 5000; ++i) {
    c.add(nan, 1.0);
    c.add(-1.0, 1.0);
    c.add(4.0, nan);
    c.add(4.0, inf);
    c.add(20.0, 1.0);  // above the configured threshold: flagged anyway
    c.add(inf, 1.0);   // beyond any bin: must not index out of range
    c.add(1e300, 1.0);
  }
  EXPECT_EQ(c.threshold(), 6.0);
  feed(c, 4.5, 4000);
  EXPECT_EQ(c.threshold(), 4.5);
  c.reset();
  EXPECT_EQ(c.threshold(), 6.0);
  EXPECT_TRUE(std::isnan(c.reference()));
}

// Gaps reported in whole dB: the ranges at 4 dB exactly are LOS, those at
// 5 dB carry an excess. The flag is gap > threshold, so the learnt edge
// must be 4 dB (bins are (lo, hi]), not 4.5 (which would leave 5 dB in).
TEST(LosGapCalibrator, QuantizedGapsSitBelowTheEdgeTheyShare) {
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  for (int i = 0; i < 4000; ++i) {
    const double gap_db = 1.0 + (i % 5);  // 1, 2, 3, 4, 5 dB
    c.add(gap_db, gap_db >= 5.0 ? 0.3 : 0.0);
  }
  EXPECT_EQ(c.threshold(), 4.5) << "the 5 dB ranges are in (4.5, 5]";
  EXPECT_LT(c.threshold(), 5.0);
}

TEST(LosGapCalibrator, NeverBelowAFloorBetweenBinEdges) {
  LosGapParams p;
  p.min_gap_db = 3.2;
  LosGapCalibrator c(p, kSigma, 6.0);
  feed(c, 2.0, 4000);
  EXPECT_GE(c.threshold(), 3.2);
}

TEST(LosGapCalibrator, OffOrWithoutAnIndicatorItLearnsNothing) {
  LosGapParams off;
  off.enabled = false;
  LosGapCalibrator c(off, kSigma, 6.0);
  feed(c, 4.0, 4000);
  EXPECT_EQ(c.threshold(), 6.0);
  const double inf = std::numeric_limits<double>::infinity();
  LosGapCalibrator none(LosGapParams(), kSigma, inf);
  feed(none, 4.0, 4000);
  EXPECT_EQ(none.threshold(), inf);
}

TEST(LosGapCalibrator, AddingNeverAllocates) {
  LosGapCalibrator c(LosGapParams(), kSigma, 6.0);
  feed(c, 4.5, 500);
  std::uint64_t news = 0;
  {
    testing::NewCounter counter;
    for (int i = 0; i < 4000; ++i) c.add(1.0 + 0.002 * i, 0.01 * (i % 7));
    news = counter.count();
  }
  EXPECT_EQ(news, 0u);
}

TEST(LosGapCalibrator, RejectsMalformedParameters) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto bad = [](LosGapParams p, const char* field, double sigma = kSigma, double max_db = 6.0) {
    try {
      LosGapCalibrator c(p, sigma, max_db);
      ADD_FAILURE() << "accepted " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  LosGapParams p;
  p.bin_db = 0.0;
  bad(p, "bin_db");
  p = {};
  p.min_gap_db = nan;
  bad(p, "min_gap_db");
  p = {};
  p.reference_ranges = 0;
  bad(p, "reference_ranges");
  p = {};
  p.min_bin_ranges = LosGapCalibrator::kPerBin + 1;
  bad(p, "min_bin_ranges");
  p = {};
  p.rx_level_max_gap_db = nan;
  bad(p, "rx_level_max_gap_db");
  p.rx_level_max_gap_db = 0.0;
  bad(p, "rx_level_max_gap_db");
  p.rx_level_max_gap_db = -1.0;
  bad(p, "rx_level_max_gap_db");
  p = {};
  p.excess_sigmas = -0.1;
  bad(p, "excess_sigmas");
  p = {};
  p.recompute_every = 0;
  bad(p, "recompute_every");
  bad(LosGapParams(), "sigma_m", 0.0);
  bad(LosGapParams(), "max_gap_db", kSigma, nan);
}

}  // namespace
}  // namespace rilo
