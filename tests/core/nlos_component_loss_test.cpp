// The asymmetric model's NLOS component alone, and how a range the receiver
// flags as NLOS becomes a range term (nlos_component_loss.h, range_model.h).
// The robust_loss.h conventions are checked for it in noise_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "estimation/measurements/range_model.h"
#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/nlos_component_loss.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {
namespace {

// The robust_loss.h properties, with tolerances for a tabulated density
// (noise_test.cpp's AnyLoss suite asks for exactness to rounding near 0,
// which only closed-form cores give).
class NlosComponentProperties : public ::testing::TestWithParam<double> {
 protected:
  static std::vector<double> residuals() {
    std::vector<double> r;
    for (double x = -30.0; x <= 30.0; x += 0.00937) r.push_back(x);
    for (double x = 1e-3; x < 1e6; x *= 1.07) {
      r.push_back(x);
      r.push_back(-x);
    }
    std::sort(r.begin(), r.end());
    return r;
  }
};

TEST_P(NlosComponentProperties, ZeroAndUnitCurvatureAtTheOrigin) {
  const NlosComponentLoss loss(GetParam());
  EXPECT_EQ(loss.loss(0.0), 0.0);
  EXPECT_EQ(loss.derivative(0.0), 0.0);
  EXPECT_EQ(loss.weight(0.0), 1.0);
  // Near kMaxGamma the table's cubic pieces give the curvature at the mode
  // to a few per cent only.
  const double rel = GetParam() > 5.0 ? 0.05 : 1e-3;
  for (const double r : {1e-3, -1e-3, 1e-2, -1e-2}) {
    EXPECT_NEAR(loss.loss(r), 0.5 * r * r, rel * r * r + 2.0 * std::abs(r * r * r)) << r;
    EXPECT_NEAR(loss.weight(r), 1.0, rel + 3.0 * std::abs(r)) << r;
  }
}

TEST_P(NlosComponentProperties, MonotoneOnEachSideWithMatchingDerivativeAndBoundedWeight) {
  const NlosComponentLoss loss(GetParam());
  const double w_max = loss.sigmaScale() * loss.sigmaScale();
  double prev = -1.0;
  int checked = 0;
  for (const double r : residuals()) {
    const double rho = loss.loss(r), d = loss.derivative(r), w = loss.weight(r);
    ASSERT_TRUE(std::isfinite(rho) && std::isfinite(d)) << r;
    ASSERT_GE(w, 0.0) << r;
    ASSERT_LE(w, w_max * (1.0 + 1e-6)) << r;
    ASSERT_NEAR(w, d / r, 1e-12 * std::max(1.0, w)) << r;
    // Sign of the slope = sign of r (rho grows away from 0 on both sides).
    if (std::abs(r) > 1e-2) {
      ASSERT_GT(d * r, 0.0) << r;
    }
    const double h = 1e-5 * std::max(1.0, std::abs(r));
    const double fd = (loss.loss(r + h) - loss.loss(r - h)) / (2.0 * h);
    ASSERT_NEAR(d, fd, 2e-5 * std::abs(d) + 1e-8 + 1e-14 * rho / h) << r;
    if (r > 0.0) {
      ASSERT_GE(rho, prev - 1e-12 * (1.0 + rho)) << r;
      prev = rho;
    }
    ++checked;
  }
  EXPECT_GT(checked, 5000);
}

INSTANTIATE_TEST_SUITE_P(Gammas, NlosComponentProperties,
                         ::testing::Values(AsymmetricLoss::kMinGamma, 0.5, 1.349, 5.0, NlosComponentLoss::kMaxGamma));

TEST(NlosComponentLoss, IsTheNlosDensityCentredOnItsModeAndScaledByItsCurvature) {
  for (const double gamma : {0.05, 0.5, 1.349, 5.0, 20.0}) {
    SCOPED_TRACE(gamma);
    const NlosComponentLoss loss(gamma);
    const AsymmetricLoss mixture(gamma, 0.2);  // same NLOS density g
    const double m = loss.modeSigmas(), s = loss.sigmaScale();
    // The half-Cauchy excess only ever lengthens: the most likely excess is > 0.
    EXPECT_GT(m, 0.0);
    // rho(r) = -log g(m + s r) + log g(m), against the mixture's own NLOS
    // branch (by quadrature below the table: the extension's accuracy).
    for (const double r : {-6.0, -1.0, -0.1, 0.3, 2.0, 10.0, 300.0}) {
      const double eps = m + s * r;
      const double tol = eps < AsymmetricLoss::kTableMinEps ? 1e-3 * loss.loss(r) : 1e-9 * (1.0 + loss.loss(r));
      EXPECT_NEAR(loss.loss(r), mixture.nlosLoss(eps) - mixture.nlosLoss(m), tol) << r;
    }
    // The mode is the density's maximum.
    for (const double d : {-1e-2, 1e-2}) EXPECT_GT(mixture.nlosDensity(m), mixture.nlosDensity(m + d));
    // Unit curvature after scaling: rho ~ r^2 / 2 near 0 (second difference).
    const double h = 1e-2;
    EXPECT_NEAR((loss.loss(h) - 2.0 * loss.loss(0.0) + loss.loss(-h)) / (h * h), 1.0, 1e-2);
  }
}

TEST(NlosComponentLoss, WiderThanTheLosGaussianAndShiftedFurtherForAWiderExcess) {
  const NlosComponentLoss narrow(0.5), wide(5.0);
  EXPECT_GE(narrow.sigmaScale(), 1.0);
  EXPECT_GT(wide.sigmaScale(), narrow.sigmaScale());
  EXPECT_GT(wide.modeSigmas(), narrow.modeSigmas());
  // Almost no excess: the component tends to the LOS Gaussian.
  const NlosComponentLoss tiny(AsymmetricLoss::kMinGamma);
  EXPECT_NEAR(tiny.modeSigmas(), 0.0, 1e-2);
  EXPECT_NEAR(tiny.sigmaScale(), 1.0, 1e-2);
}

TEST(NlosComponentLoss, HeavyTailOnTheLongSideGaussianOnTheShortSide) {
  const NlosComponentLoss loss(1.349);
  // Long: the weight falls like a Cauchy's; short: it stays near 1.
  EXPECT_LT(loss.weight(20.0), 0.05);
  EXPECT_GT(loss.weight(-3.0), 0.5);
  EXPECT_GT(loss.loss(-10.0), loss.loss(10.0));
}

TEST(NlosComponentLoss, ContinuousAcrossTheTablesLowEnd) {
  // Far on the short side the density continues quadratically from the table.
  const NlosComponentLoss loss(1.349);
  const double r_edge = (AsymmetricLoss::kTableMinEps - loss.modeSigmas()) / loss.sigmaScale();
  const double eps = 1e-7;
  EXPECT_NEAR(loss.loss(r_edge - eps), loss.loss(r_edge + eps), 1e-5);
  EXPECT_NEAR(loss.derivative(r_edge - eps), loss.derivative(r_edge + eps), 1e-4);
  EXPECT_TRUE(std::isfinite(loss.loss(-1e6)));
  // The extension against the quadrature, far out.
  const AsymmetricLoss mixture(1.349, 0.2);
  for (const double e : {-9.0, -20.0, -100.0, -1000.0}) {
    EXPECT_NEAR(mixture.nlosNegLogDensity(e, nullptr), mixture.nlosLoss(e) - mixture.nlosLoss(0.0) +
                                                             mixture.nlosNegLogDensity(0.0, nullptr),
                1e-3 * std::abs(mixture.nlosLoss(e)))
        << e;
  }
}

TEST(NlosComponentLoss, InvalidScaleThrows) {
  EXPECT_THROW(NlosComponentLoss(0.0), std::invalid_argument);
  EXPECT_THROW(NlosComponentLoss(NlosComponentLoss::kMaxGamma * 1.01), std::invalid_argument);
  EXPECT_THROW(NlosComponentLoss(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  RangeNoiseParams p;
  p.sigma_m = -1.0;
  EXPECT_THROW(makeNlosComponentLoss(p), std::invalid_argument);
}

Measurement rangeWithGap(double gap_db) {
  RangeSample s;
  s.t_ns = 1;
  s.anchor_id = 2;
  s.range_m = 7.0;
  s.rssi_dbm = -80.0;
  s.fp_power_dbm = -80.0 - gap_db;
  return Measurement::of(s);
}

TEST(RangeModel, FlaggedRangesGetTheMixtureWithTheLargerNlosPriorOnRequest) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  noise.flagged_nlos_component = false;
  const RangeModel model("asymmetric", noise);
  ASSERT_TRUE(model.usesIndicator());
  const RangeTerm flagged = model.term(rangeWithGap(9.0), 0.1);
  EXPECT_TRUE(flagged.flagged_nlos);
  const auto* mixture = dynamic_cast<const AsymmetricLoss*>(flagged.loss.get());
  ASSERT_NE(mixture, nullptr);
  EXPECT_DOUBLE_EQ(mixture->nlosWeight(), noise.flagged_nlos_weight);
  EXPECT_EQ(flagged.range_m, 7.0);
  EXPECT_EQ(flagged.sigma_m, 0.1);
  // Its decision point is lower: a flagged range leaves the Gaussian core sooner.
  const auto* plain = dynamic_cast<const AsymmetricLoss*>(model.loss().get());
  ASSERT_NE(plain, nullptr);
  EXPECT_LT(mixture->decisionPoint(), plain->decisionPoint());
  EXPECT_FALSE(model.term(rangeWithGap(3.0), 0.1).flagged_nlos);
  // The site's expected excess (Localizer: FlaggedExcessParams) comes off flagged ranges only.
  RangeModel shifted("asymmetric", noise);
  shifted.setFlaggedExcess(0.25);
  EXPECT_DOUBLE_EQ(shifted.term(rangeWithGap(9.0), 0.1).range_m, 7.0 - 0.25);
  EXPECT_DOUBLE_EQ(shifted.term(rangeWithGap(3.0), 0.1).range_m, 7.0);
  noise.flagged_nlos_weight = 0.6;
  EXPECT_THROW(RangeModel("asymmetric", noise), std::invalid_argument) << "the mixture needs w < 0.5";
}

// The Localizer's calibrated threshold (los_gap_calibration.h) replaces the
// configured one; without the indicator it changes nothing.
TEST(RangeModel, TakesTheSitesFlagThreshold) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  RangeModel model("asymmetric", noise);
  EXPECT_EQ(model.nlosGapDb(), 6.0);
  EXPECT_FALSE(model.flagsNlos(rangeWithGap(4.5)));
  model.setNlosGapDb(4.0);
  EXPECT_TRUE(model.flagsNlos(rangeWithGap(4.5)));
  EXPECT_TRUE(model.term(rangeWithGap(4.5), 0.1).flagged_nlos);
  EXPECT_FALSE(model.flagsNlos(rangeWithGap(4.0))) << "above the threshold, not at it";
  RangeModel gaussian("gaussian", noise);
  gaussian.setNlosGapDb(4.0);
  EXPECT_FALSE(gaussian.flagsNlos(rangeWithGap(9.0)));
}

TEST(RangeModel, FlaggedRangesTakeTheirGapBinsExcessWhereThereIsOne) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  RangeModel model("asymmetric", noise);
  model.setNlosGapDb(4.0);
  model.setFlaggedExcess(0.05);
  GapExcessTable table;
  table.excess_m[8] = 0.2;  // (4.0, 4.5] dB
  model.setGapExcess(table);
  const RangeTerm in_bin = model.term(rangeWithGap(4.3), 0.1);
  EXPECT_TRUE(in_bin.flagged_nlos);
  EXPECT_DOUBLE_EQ(in_bin.range_m, 7.0 - 0.2);
  EXPECT_DOUBLE_EQ(model.term(rangeWithGap(9.0), 0.1).range_m, 7.0 - 0.05) << "no bin: the site's excess";
  EXPECT_DOUBLE_EQ(model.term(rangeWithGap(4.7), 0.1).range_m, 7.0 - 0.05) << "a bin without an estimate";
  // Unflagged ranges are left alone even where their bin has an excess.
  table.excess_m[6] = 0.1;  // (3.0, 3.5] dB, below the threshold
  model.setGapExcess(table);
  EXPECT_DOUBLE_EQ(model.term(rangeWithGap(3.2), 0.1).range_m, 7.0);
  // The mixture variant takes the same shift.
  noise.flagged_nlos_component = false;
  RangeModel mixture("asymmetric", noise);
  mixture.setNlosGapDb(4.0);
  mixture.setGapExcess(table);
  EXPECT_DOUBLE_EQ(mixture.term(rangeWithGap(4.3), 0.1).range_m, 7.0 - 0.2);
}

TEST(RangeModel, FlaggedRangesTakeTheirOwnExcessScaleWhenGiven) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  noise.flagged_nlos_scale_m = 0.5;
  noise.flagged_nlos_component = false;
  const RangeModel model("asymmetric", noise);
  const auto* flagged = dynamic_cast<const AsymmetricLoss*>(model.term(rangeWithGap(9.0), 0.1).loss.get());
  const auto* clear = dynamic_cast<const AsymmetricLoss*>(model.term(rangeWithGap(3.0), 0.1).loss.get());
  ASSERT_NE(flagged, nullptr);
  ASSERT_NE(clear, nullptr);
  EXPECT_DOUBLE_EQ(flagged->gamma(), 5.0) << "0.5 m in LOS sigmas";
  EXPECT_DOUBLE_EQ(clear->gamma(), noise.nlosScaleM() / 0.1) << "unflagged ranges keep the shared scale";
  EXPECT_DOUBLE_EQ(flagged->nlosWeight(), noise.flagged_nlos_weight);
  // The NLOS component alone takes it too.
  noise.flagged_nlos_component = true;
  const RangeModel component("asymmetric", noise);
  const auto* alone = dynamic_cast<const NlosComponentLoss*>(component.term(rangeWithGap(9.0), 0.1).loss.get());
  ASSERT_NE(alone, nullptr);
  EXPECT_DOUBLE_EQ(alone->gamma(), 5.0);
  noise.flagged_nlos_scale_m = 0.0;
  try {
    RangeModel bad("asymmetric", noise);
    FAIL() << "a scale must be > 0";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("flagged_nlos_scale_m"), std::string::npos) << e.what();
  }
}

TEST(RangeModel, FlaggedRangesGetTheNlosComponentShiftedAndWidenedByDefault) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  ASSERT_TRUE(noise.flagged_nlos_component);
  const RangeModel model("asymmetric", noise);
  ASSERT_TRUE(model.usesIndicator());
  const std::shared_ptr<const NlosComponentLoss> nlos = makeNlosComponentLoss(noise.flagged());
  EXPECT_DOUBLE_EQ(nlos->gamma(), RangeNoiseParams::kDefaultFlaggedComponentScaleM / 0.1)
      << "unset flagged scale: the component's own default, 1 m";

  const RangeTerm flagged = model.term(rangeWithGap(9.0), 0.1);
  EXPECT_TRUE(flagged.flagged_nlos);
  EXPECT_EQ(flagged.loss, nlos);
  EXPECT_DOUBLE_EQ(flagged.range_m, 7.0 - nlos->modeSigmas() * 0.1) << "no excess set: the component's mode";
  EXPECT_DOUBLE_EQ(flagged.sigma_m, 0.1 * nlos->sigmaScale());
  EXPECT_LT(flagged.range_m, 7.0);
  EXPECT_GT(nlos->sigmaScale(), 2.0) << "a flagged range weighs much less than a clear one";

  // At or below the threshold, or without powers: the mixture, untouched.
  for (const Measurement& m : {rangeWithGap(6.0), rangeWithGap(2.0), Measurement::of(RangeSample{})}) {
    const RangeTerm t = model.term(m, 0.1);
    EXPECT_FALSE(t.flagged_nlos);
    EXPECT_EQ(t.loss, model.loss());
    EXPECT_EQ(t.range_m, m.value_m);
    EXPECT_EQ(t.sigma_m, 0.1);
  }
  EXPECT_TRUE(std::isnan(Measurement::of(RangeSample{}).power_gap_db)) << "no powers: no indicator";
}

TEST(RangeModel, ASetExcessReplacesTheComponentsModeEvenWhenZero) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  RangeModel model("asymmetric", noise);
  const std::shared_ptr<const NlosComponentLoss> nlos = makeNlosComponentLoss(noise.flagged());
  ASSERT_GT(nlos->modeSigmas(), 0.5);
  model.setFlaggedExcess(0.0);  // what the Localizer sets before its estimate has enough ranges
  const RangeTerm zero = model.term(rangeWithGap(9.0), 0.1);
  EXPECT_DOUBLE_EQ(zero.range_m, 7.0) << "attenuated-only sites: no shift for nothing";
  EXPECT_DOUBLE_EQ(zero.sigma_m, 0.1 * nlos->sigmaScale()) << "still the component's width";
  EXPECT_EQ(zero.loss, nlos);
  model.setFlaggedExcess(0.3);
  EXPECT_DOUBLE_EQ(model.term(rangeWithGap(9.0), 0.1).range_m, 7.0 - 0.3);
  EXPECT_DOUBLE_EQ(model.term(rangeWithGap(3.0), 0.1).range_m, 7.0) << "unflagged ranges keep their value";
}

// A flag from the RX level (Localizer::withRxLevelIndicator) says a path is
// attenuated, not how much it is delayed: the site's flagged excess, learnt
// from the receiver's own flags, is not taken off it; its gap bin's excess,
// where the calibration measured one, is.
TEST(RangeModel, RxLevelFlagsTakeTheComponentsModeNotTheSitesExcess) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  RangeModel model("asymmetric", noise);
  const std::shared_ptr<const NlosComponentLoss> nlos = makeNlosComponentLoss(noise.flagged());
  model.setFlaggedExcess(0.3);
  Measurement rx = rangeWithGap(9.0);
  rx.gap_from_rx_level = true;
  const RangeTerm t = model.term(rx, 0.1);
  EXPECT_TRUE(t.flagged_nlos);
  EXPECT_DOUBLE_EQ(t.range_m, 7.0 - nlos->modeSigmas() * 0.1);
  EXPECT_DOUBLE_EQ(model.term(rangeWithGap(9.0), 0.1).range_m, 7.0 - 0.3) << "the receiver's own flag";
  GapExcessTable table;
  table.excess_m[17] = 0.2;  // (8.5, 9.0] dB
  model.setGapExcess(table);
  EXPECT_DOUBLE_EQ(model.term(rx, 0.1).range_m, 7.0 - 0.2);
  // The mixture variant: no site shift either.
  noise.flagged_nlos_component = false;
  RangeModel mixture("asymmetric", noise);
  mixture.setFlaggedExcess(0.3);
  EXPECT_DOUBLE_EQ(mixture.term(rx, 0.1).range_m, 7.0);
  EXPECT_DOUBLE_EQ(mixture.term(rangeWithGap(9.0), 0.1).range_m, 7.0 - 0.3);
  // Measurement::of carries the mark from the sample.
  RangeSample s;
  s.range_m = 7.0;
  s.rssi_dbm = -80.0;
  s.fp_power_dbm = -89.0;
  s.fp_from_rx_level = true;
  s.tag_id = 3;
  const Measurement m = Measurement::of(s);
  EXPECT_TRUE(m.gap_from_rx_level);
  EXPECT_EQ(m.tag, 3u);
  EXPECT_DOUBLE_EQ(m.power_gap_db, 9.0);
}

// A range the anchor's memory flags (nlos_memory.h) while its gap is a LOS
// one takes the NLOS component at its mode: neither its LOS gap bin's
// excess nor the site's flagged excess, which belong to the receiver's flags.
TEST(RangeModel, ARangeFlaggedByItsAnchorsMemoryTakesTheComponentsMode) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  RangeModel model("asymmetric", noise);
  const std::shared_ptr<const NlosComponentLoss> nlos = makeNlosComponentLoss(noise.flagged());
  model.setFlaggedExcess(0.3);
  GapExcessTable table;
  table.excess_m[5] = 0.05;  // (2.5, 3.0] dB: a LOS bin with a small excess
  model.setGapExcess(table);
  Measurement m = rangeWithGap(3.0);
  EXPECT_FALSE(model.flagsNlos(m));
  m.nlos_from_memory = true;
  EXPECT_TRUE(model.flagsNlos(m));
  const RangeTerm t = model.term(m, 0.1);
  EXPECT_TRUE(t.flagged_nlos);
  EXPECT_DOUBLE_EQ(t.range_m, 7.0 - nlos->modeSigmas() * 0.1);
  EXPECT_DOUBLE_EQ(t.sigma_m, 0.1 * nlos->sigmaScale());
  // Without any power (a receiver reporting neither): flagged the same way.
  Measurement bare = m;
  bare.power_gap_db = std::numeric_limits<double>::quiet_NaN();
  EXPECT_DOUBLE_EQ(model.term(bare, 0.1).range_m, 7.0 - nlos->modeSigmas() * 0.1);
  // Its gap above the threshold: the receiver's flag rules, with its shift.
  Measurement both = rangeWithGap(9.0);
  both.nlos_from_memory = true;
  EXPECT_DOUBLE_EQ(model.term(both, 0.1).range_m, 7.0 - 0.3);
  // The mixture variant: no shift.
  noise.flagged_nlos_component = false;
  RangeModel mixture("asymmetric", noise);
  mixture.setFlaggedExcess(0.3);
  EXPECT_DOUBLE_EQ(mixture.term(m, 0.1).range_m, 7.0);
  // No indicator (threshold +inf) or a symmetric model: nothing is flagged.
  noise.nlos_power_gap_db = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(RangeModel("asymmetric", noise).flagsNlos(m));
  EXPECT_FALSE(RangeModel("huber", RangeNoiseParams()).flagsNlos(m));
  // Measurement::of carries the mark from the sample.
  RangeSample s;
  s.nlos_from_memory = true;
  EXPECT_TRUE(Measurement::of(s).nlos_from_memory);
}

TEST(RangeModel, TheDefaultComponentScaleStaysWithinTheTableAtSmallSigmas) {
  RangeNoiseParams noise;
  noise.sigma_m = 0.02;  // 1 m would be 50 sigmas, beyond NlosComponentLoss::kMaxGamma
  const RangeModel model("asymmetric", noise);  // must not throw
  const auto* alone = dynamic_cast<const NlosComponentLoss*>(model.term(rangeWithGap(9.0), 0.02).loss.get());
  ASSERT_NE(alone, nullptr);
  EXPECT_DOUBLE_EQ(alone->gamma(), NlosComponentLoss::kMaxGamma);
  noise.flagged_nlos_scale_m = 1.0;  // given explicitly: refused, naming the limit
  EXPECT_THROW(RangeModel("asymmetric", noise), std::invalid_argument);
  noise.flagged_nlos_scale_m.reset();
  noise.flagged_nlos_component = false;
  EXPECT_DOUBLE_EQ(noise.flagged().nlosScaleM(), noise.nlosScaleM()) << "the mixture keeps the shared scale";
}

TEST(RangeModel, TheDefaultComponentScaleWidensWithTheSquareRootOfTheRangingRateAboveTheReference) {
  RangeNoiseParams noise;  // sigma 0.15 m: the table allows up to 3 m
  ASSERT_DOUBLE_EQ(noise.flagged_scale_reference_hz, 10.0);
  EXPECT_DOUBLE_EQ(noise.flaggedComponentScaleAt(0.0), 1.0) << "rate unknown";
  EXPECT_DOUBLE_EQ(noise.flaggedComponentScaleAt(1.0), 1.0);
  EXPECT_DOUBLE_EQ(noise.flaggedComponentScaleAt(10.0), 1.0);
  EXPECT_DOUBLE_EQ(noise.flaggedComponentScaleAt(40.0), 2.0);
  EXPECT_DOUBLE_EQ(noise.flaggedComponentScaleAt(20.0), std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(noise.flaggedComponentScaleAt(1000.0), NlosComponentLoss::kMaxGamma * 0.15) << "capped at the table";
  EXPECT_DOUBLE_EQ(noise.flagged().nlosScaleM(), 1.0) << "flagged() alone knows no rate";
  noise.flagged_scale_reference_hz = 0.0;
  EXPECT_DOUBLE_EQ(noise.flaggedComponentScaleAt(40.0), 1.0) << "0 turns the widening off";
  for (double bad : {-1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    noise.flagged_scale_reference_hz = bad;
    try {
      RangeModel model("asymmetric", noise);
      FAIL() << "expected std::invalid_argument for " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("flagged_scale_reference_hz"), std::string::npos) << e.what();
    }
  }
}

TEST(RangeModel, OnlyTheConvolvedAsymmetricModelUsesTheIndicator) {
  RangeNoiseParams noise;
  for (const char* name : {"gaussian", "huber", "cauchy", "asymmetric-half-cauchy"}) {
    SCOPED_TRACE(name);
    const RangeModel model(name, noise);
    EXPECT_FALSE(model.usesIndicator());
    EXPECT_FALSE(model.term(rangeWithGap(20.0), 0.15).flagged_nlos);
  }
  noise.nlos_power_gap_db = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(RangeModel("asymmetric", noise).usesIndicator()) << "+inf turns it off";
  // TDoA and ultrasonic measurements are never flagged (no powers).
  noise.nlos_power_gap_db = 6.0;
  Measurement tdoa = rangeWithGap(20.0);
  tdoa.kind = Measurement::Kind::kTdoa;
  EXPECT_FALSE(RangeModel("asymmetric", noise).flagsNlos(tdoa));
}

TEST(RangeModel, BadParametersNameTheField) {
  RangeNoiseParams noise;
  noise.nlos_power_gap_db = std::numeric_limits<double>::quiet_NaN();
  try {
    RangeModel model("asymmetric", noise);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("nlos_power_gap_db"), std::string::npos) << e.what();
  }
  EXPECT_THROW(RangeModel("bogus", RangeNoiseParams{}), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
