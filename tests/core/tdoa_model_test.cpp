// TdoaModel: how a TDoA row enters the estimators from its packets' receive
// diagnostics (no diagnostics or unflagged: as configured; one packet flagged:
// oriented so the flagged path is b's, NLOS-tail loss; both: widened).
#include "estimation/measurements/tdoa_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "estimation/factors/tdoa_factor.h"

namespace rilo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Measurement tdoaRow(double gap_a_db, double gap_b_db, double diff_m = 1.25) {
  TdoaSample s;
  s.t_ns = 1000;
  s.anchor_a = 3;
  s.anchor_b = 5;
  s.diff_m = diff_m;
  s.rssi_a_dbm = -80.0;
  s.fp_power_a_dbm = -80.0 - gap_a_db;
  s.rssi_b_dbm = -85.0;
  s.fp_power_b_dbm = -85.0 - gap_b_db;
  return Measurement::of(s);
}

TdoaModel defaultModel() { return TdoaModel(TdoaModelParams{}, RangeNoiseParams{}); }

TEST(TdoaModel, MeasurementCarriesBothPacketsGaps) {
  const Measurement m = tdoaRow(2.5, 9.0);
  EXPECT_EQ(m.kind, Measurement::Kind::kTdoa);
  EXPECT_DOUBLE_EQ(m.power_gap_db, 2.5);
  EXPECT_DOUBLE_EQ(m.power_gap_b_db, 9.0);
  EXPECT_TRUE(std::isnan(Measurement::of(TdoaSample{}).power_gap_b_db));
}

TEST(TdoaModel, UnflaggedOrUndiagnosedRowsKeepTheConfiguredLossAndSigma) {
  const TdoaModel model = defaultModel();
  for (const Measurement& m : {tdoaRow(2.0, 3.0), tdoaRow(kNaN, kNaN), tdoaRow(6.0, 6.0)}) {
    EXPECT_EQ(model.flaggedPackets(m), 0);
    const TdoaTerm t = model.term(m, 0.2);
    EXPECT_EQ(t.anchor_a, 3u);
    EXPECT_EQ(t.anchor_b, 5u);
    EXPECT_EQ(t.value_m, 1.25);
    EXPECT_EQ(t.sigma_m, 0.2);
    EXPECT_EQ(t.loss, model.loss());
    EXPECT_FALSE(t.reversed);
    EXPECT_EQ(model.symmetricSigma(m, 0.2), 0.2);
  }
  EXPECT_EQ(model.loss()->name(), "huber");
}

TEST(TdoaModel, FlaggedBPacketGetsTheNlosTailOnTheLongSide) {
  const TdoaModel model = defaultModel();
  const Measurement m = tdoaRow(2.0, 12.0);
  EXPECT_EQ(model.flaggedPackets(m), 1);
  const TdoaTerm t = model.term(m, 0.15);
  EXPECT_EQ(t.flagged_packets, 1);
  EXPECT_FALSE(t.reversed);
  EXPECT_EQ(t.anchor_a, 3u);
  EXPECT_EQ(t.anchor_b, 5u);
  EXPECT_EQ(t.value_m, 1.25);
  EXPECT_EQ(t.sigma_m, 0.15);
  ASSERT_NE(t.loss, model.loss());
  EXPECT_FALSE(t.loss->isSymmetric());
  // b's path late: r > 0 (tdoa_factor.h) is the tail's side, cheap and down-weighted.
  EXPECT_LT(t.loss->loss(6.0), t.loss->loss(-6.0));
  EXPECT_LT(t.loss->weight(6.0), 0.5 * t.loss->weight(-6.0));
  EXPECT_DOUBLE_EQ(model.symmetricSigma(m, 0.15), 0.15 * TdoaModelParams{}.one_flagged_sigma_factor);
}

TEST(TdoaModel, FlaggedReferencePacketIsReversedSoItsDelayIsTheLongSide) {
  const TdoaModel model = defaultModel();
  const Measurement m = tdoaRow(15.0, 2.0);
  const TdoaTerm t = model.term(m, 0.15);
  EXPECT_EQ(t.flagged_packets, 1);
  EXPECT_TRUE(t.reversed);
  EXPECT_EQ(t.anchor_a, 5u);
  EXPECT_EQ(t.anchor_b, 3u);
  EXPECT_EQ(t.value_m, -1.25);
  EXPECT_FALSE(t.loss->isSymmetric());

  // The reversed factor is the same measurement: opposite residual, same
  // Jacobian up to sign, and a's NLOS delay now lands on r > 0.
  const Vec3 p_w_a(3, 4, 0), p_w_b(6, 8, 0);  // h = 5 at the origin
  Values x;
  x.insert(sym::X(0), Pose3());
  const double a_late_diff = 5.0 - 0.6;       // a's path 0.6 m long: the difference reads short
  Residual r_orig, r_term;
  Jacobians H_orig, H_term;
  TdoaFactor(sym::X(0), p_w_a, p_w_b, a_late_diff, 0.15, Vec3::Zero()).evaluate(x, r_orig, &H_orig);
  TdoaFactor(sym::X(0), p_w_b, p_w_a, -a_late_diff, 0.15, Vec3::Zero()).evaluate(x, r_term, &H_term);
  EXPECT_LT(r_orig(0), 0.0);
  EXPECT_NEAR(r_term(0), -r_orig(0), 1e-12);
  EXPECT_TRUE(H_term[0].isApprox(-H_orig[0], 1e-12));
  EXPECT_LT(t.loss->weight(r_term(0)), 0.5 * t.loss->weight(r_orig(0)));
}

TEST(TdoaModel, BothFlaggedAreWidenedWithTheConfiguredLoss) {
  TdoaModelParams p;
  p.both_flagged_sigma_factor = 4.0;
  const TdoaModel model(p, RangeNoiseParams{});
  const Measurement m = tdoaRow(9.0, 20.0);
  EXPECT_EQ(model.flaggedPackets(m), 2);
  const TdoaTerm t = model.term(m, 0.1);
  EXPECT_FALSE(t.reversed);
  EXPECT_EQ(t.value_m, 1.25);
  EXPECT_DOUBLE_EQ(t.sigma_m, 0.4);
  EXPECT_EQ(t.loss, model.loss());
  EXPECT_DOUBLE_EQ(model.symmetricSigma(m, 0.1), 0.4);
}

TEST(TdoaModel, IndicatorOffOrDisabledThresholdFlagsNothing) {
  TdoaModelParams off;
  off.use_indicator = false;
  RangeNoiseParams no_gap;
  no_gap.nlos_power_gap_db = std::numeric_limits<double>::infinity();
  for (const TdoaModel& model : {TdoaModel(off, RangeNoiseParams{}), TdoaModel(TdoaModelParams{}, no_gap)}) {
    const TdoaTerm t = model.term(tdoaRow(30.0, 30.0), 0.15);
    EXPECT_EQ(t.flagged_packets, 0);
    EXPECT_EQ(t.sigma_m, 0.15);
    EXPECT_EQ(t.loss, model.loss());
  }
  // Two-way ranges are not TDoA rows.
  RangeSample r;
  r.rssi_dbm = -80.0;
  r.fp_power_dbm = -100.0;
  EXPECT_EQ(defaultModel().flaggedPackets(Measurement::of(r)), 0);
}

TEST(TdoaModel, ThresholdIsTheRangeNoiseGap) {
  RangeNoiseParams noise;
  noise.nlos_power_gap_db = 10.0;
  const TdoaModel model(TdoaModelParams{}, noise);
  EXPECT_EQ(model.flaggedPackets(tdoaRow(9.0, 11.0)), 1);
  EXPECT_FALSE(model.term(tdoaRow(9.0, 11.0), 0.15).reversed);
  EXPECT_TRUE(model.term(tdoaRow(11.0, 9.0), 0.15).reversed);
}

TEST(TdoaModel, OnlyRowsWithBothDiagnosticsUnflaggedAreVouchedLos) {
  const TdoaModel model = defaultModel();
  EXPECT_TRUE(model.vouchedLos(tdoaRow(2.0, 3.0)));
  EXPECT_TRUE(model.vouchedLos(tdoaRow(6.0, 6.0)));  // at the threshold: not above it
  EXPECT_FALSE(model.vouchedLos(tdoaRow(2.0, 9.0)));
  EXPECT_FALSE(model.vouchedLos(tdoaRow(9.0, 2.0)));
  EXPECT_FALSE(model.vouchedLos(tdoaRow(9.0, 9.0)));
  EXPECT_FALSE(model.vouchedLos(tdoaRow(2.0, kNaN)));  // one packet unreported: not vouched for
  EXPECT_FALSE(model.vouchedLos(tdoaRow(kNaN, kNaN)));
  TdoaModelParams off;
  off.use_indicator = false;
  EXPECT_FALSE(TdoaModel(off, RangeNoiseParams{}).vouchedLos(tdoaRow(2.0, 3.0)));
  RangeSample r;
  r.rssi_dbm = -80.0;
  r.fp_power_dbm = -81.0;
  EXPECT_FALSE(model.vouchedLos(Measurement::of(r)));
}

TEST(TdoaModel, RowsWithAPacketDeeperThanTheGateAreGated) {
  const TdoaModel model = defaultModel();  // gate at 15 dB
  EXPECT_FALSE(model.gated(tdoaRow(2.0, 3.0)));
  EXPECT_FALSE(model.gated(tdoaRow(15.0, 15.0)));  // at the gate: not above it
  EXPECT_TRUE(model.gated(tdoaRow(15.5, 3.0)));   // either packet
  EXPECT_TRUE(model.gated(tdoaRow(3.0, 20.0)));
  EXPECT_TRUE(model.gated(tdoaRow(kNaN, 20.0)));  // the reported packet decides
  EXPECT_FALSE(model.gated(tdoaRow(kNaN, kNaN)));  // no diagnostics: never gated
  TdoaModelParams open;
  open.max_power_gap_db = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(TdoaModel(open, RangeNoiseParams{}).gated(tdoaRow(40.0, 40.0)));
  TdoaModelParams strict;
  strict.max_power_gap_db = 8.0;
  EXPECT_TRUE(TdoaModel(strict, RangeNoiseParams{}).gated(tdoaRow(9.0, 2.0)));
  TdoaModelParams off;  // the indicator off: diagnostics are not used at all
  off.use_indicator = false;
  EXPECT_FALSE(TdoaModel(off, RangeNoiseParams{}).gated(tdoaRow(40.0, 40.0)));
  RangeSample r;  // a two-way range is not a TDoA row
  r.rssi_dbm = -80.0;
  r.fp_power_dbm = -110.0;
  EXPECT_FALSE(model.gated(Measurement::of(r)));
}

TEST(TdoaModel, BadParametersThrowNamingThem) {
  TdoaModelParams p;
  p.both_flagged_sigma_factor = 0.5;
  EXPECT_THROW(TdoaModel(p, RangeNoiseParams{}), std::invalid_argument);
  p = {};
  p.one_flagged_sigma_factor = std::numeric_limits<double>::infinity();
  EXPECT_THROW(TdoaModel(p, RangeNoiseParams{}), std::invalid_argument);
  p = {};
  p.flagged_loss = "lorentzian";
  EXPECT_THROW(TdoaModel(p, RangeNoiseParams{}), std::invalid_argument);
  RangeNoiseParams noise;
  noise.nlos_power_gap_db = kNaN;
  try {
    TdoaModel(TdoaModelParams{}, noise);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("nlos_power_gap_db"), std::string::npos);
  }
  p = {};
  p.max_power_gap_db = -std::numeric_limits<double>::infinity();  // would drop every row with diagnostics
  EXPECT_THROW(TdoaModel(p, RangeNoiseParams{}), std::invalid_argument);
  p.max_power_gap_db = kNaN;
  try {
    TdoaModel(p, RangeNoiseParams{});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_power_gap_db"), std::string::npos);
  }
}

}  // namespace
}  // namespace rilo
