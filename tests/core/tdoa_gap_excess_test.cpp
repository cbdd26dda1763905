// TdoaGapExcess (tdoa_gap_excess.h): the per gap bin NLOS excess of a TDoA
// packet, learnt from rows' residuals r = f(g_b) - f(g_a) + noise. It
// recovers a growing excess through multipath outliers, stays near zero when
// the gap says nothing, leaves rows without diagnostics alone, and wires
// into MeasurementNoise so the graph stream's post-fit residuals feed it.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "estimation/assembly/measurement_noise.h"
#include "estimation/noise/tdoa_gap_excess.h"
#include "estimation/tracking/ekf_estimator.h"

namespace rilo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The excess the rows are drawn with: none below 3 dB, then 0.1 m per dB.
double trueExcess(double gap_db) { return gap_db < 3.0 ? 0.0 : 0.1 * (std::floor(gap_db) - 2.0); }

/// `rows` rows with gaps uniform in [0, 15) dB, LOS noise 0.15 m and 10 %
/// multipath outliers of +0..3 m on either packet; `informative` false draws
/// the residual without the excess (a gap that says nothing).
void feed(TdoaGapExcess& learner, int rows, bool informative, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> gap(0.0, 15.0), unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.15);
  for (int i = 0; i < rows; ++i) {
    const double g_a = gap(rng), g_b = gap(rng);
    double r = noise(rng);
    if (informative) r += trueExcess(g_b) - trueExcess(g_a);
    if (unit(rng) < 0.1) r += (unit(rng) < 0.5 ? 1.0 : -1.0) * 3.0 * unit(rng);
    learner.add(g_a, g_b, r);
  }
}

TEST(TdoaGapExcess, RecoversAnExcessGrowingWithTheGapThroughOutliers) {
  TdoaGapExcess learner;
  feed(learner, 40'000, true, 1);
  for (double g = 0.5; g < 15.0; g += 1.0) {
    EXPECT_NEAR(learner.excess(g), trueExcess(g), 0.06) << "gap " << g << " dB";
  }
  EXPECT_EQ(learner.excess(2.5), 0.0);  // below los_gap_db: the gauge
  EXPECT_NEAR(learner.correction(3.5, 12.5), trueExcess(12.5) - trueExcess(3.5), 0.1);
  EXPECT_DOUBLE_EQ(learner.correction(3.5, 12.5), -learner.correction(12.5, 3.5));
}

TEST(TdoaGapExcess, StaysNearZeroWhenTheGapSaysNothing) {
  TdoaGapExcess learner;
  feed(learner, 40'000, false, 2);
  for (double g = 3.5; g < 15.0; g += 1.0) EXPECT_NEAR(learner.excess(g), 0.0, 0.06) << "gap " << g << " dB";
}

TEST(TdoaGapExcess, RowsWithoutDiagnosticsAndLosRowsTeachNothingAndGetNoCorrection) {
  TdoaGapExcess learner;
  for (int i = 0; i < 1000; ++i) {
    learner.add(kNaN, 9.0, 2.0);
    learner.add(9.0, kNaN, 2.0);
    learner.add(1.0, 2.0, 2.0);  // both below los_gap_db
    learner.add(9.2, 9.7, 2.0);  // one bin on both sides
    learner.add(4.0, 9.0, kNaN);
  }
  EXPECT_EQ(learner.rowsLearnt(), 0u);
  EXPECT_EQ(learner.rows(9.0), 0);
  EXPECT_EQ(learner.correction(kNaN, 9.0), 0.0);
  EXPECT_EQ(learner.correction(1.0, 2.0), 0.0);
}

TEST(TdoaGapExcess, ABinIsUsedOnlyOnceItHasMinRowsAndResetForgets) {
  TdoaGapExcessParams p;
  p.min_rows = 10;
  TdoaGapExcess learner(p);
  for (int i = 0; i < 9; ++i) learner.add(1.0, 8.5, 0.4);
  EXPECT_EQ(learner.rows(8.5), 9);
  EXPECT_EQ(learner.excess(8.5), 0.0);
  learner.add(1.0, 8.5, 0.4);
  EXPECT_NEAR(learner.excess(8.5), 0.4, 1e-12);  // 1/n steps: the mean of its rows
  EXPECT_NEAR(learner.correction(1.0, 8.5), 0.4, 1e-12);
  learner.reset();
  EXPECT_EQ(learner.rows(8.5), 0);
  EXPECT_EQ(learner.excess(8.5), 0.0);
}

TEST(TdoaGapExcess, OneOutlierMovesAWarmBinByAtMostClipOverWindow) {
  TdoaGapExcess learner;
  for (int i = 0; i < 1000; ++i) learner.add(1.0, 8.5, 0.3);
  const double before = learner.excess(8.5);
  learner.add(1.0, 8.5, 50.0);
  EXPECT_NEAR(learner.excess(8.5) - before, learner.params().clip_m / learner.params().window_rows, 1e-12);
}

TEST(TdoaGapExcess, BadParametersAreRefusedNamingTheField) {
  auto refused = [](TdoaGapExcessParams p, const std::string& field) {
    try {
      TdoaGapExcess learner(p);
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
      return;
    }
    ADD_FAILURE() << field << " not refused";
  };
  TdoaGapExcessParams p;
  p.bin_db = 0.0;
  refused(p, "bin_db");
  p = {};
  p.los_gap_db = kNaN;
  refused(p, "los_gap_db");
  p = {};
  p.clip_m = -1.0;
  refused(p, "clip_m");
  p = {};
  p.window_rows = 0.5;
  refused(p, "window_rows");
  p = {};
  p.min_rows = 0;
  refused(p, "min_rows");
}

// MeasurementNoise keeps TDoA rows for their post-fit residual when the
// learner is on, even without dynamic covariance, and feeds it raw residuals.
TEST(TdoaGapExcess, MeasurementNoiseFeedsItPostFitResidualsOfTdoaRows) {
  const std::vector<Vec3> anchors = {Vec3(0, 0, 2.5), Vec3(8, 0, 0.5), Vec3(8, 8, 2.5), Vec3(0, 8, 0.5)};
  RangeImuGraphParams graph;
  graph.tdoa_gap_excess.min_rows = 1;
  MeasurementNoise noise(anchors, graph, DynamicCovarianceOptions());
  const TdoaGapExcess* learner = noise.tdoaGapExcess();
  ASSERT_NE(learner, nullptr);
  EXPECT_FALSE(noise.dynamic());
  const Pose3 T_w_b(Mat3::Identity(), Vec3(4.0, 3.0, 1.2));
  Measurement m{Measurement::Kind::kTdoa, 0, 0, 2, 0.0};
  m.power_gap_db = 1.0;   // LOS reference packet
  m.power_gap_b_db = 10.5;  // anchor 2's packet deep in NLOS
  m.value_m = noise.predict(m, T_w_b) + 0.4;  // within clip_m: the first row sets the bin
  noise.notePrediction(5, 0, m, T_w_b, Vec3::Zero());
  EXPECT_EQ(noise.pending(), 1u);
  noise.notePostFit(5, T_w_b, Vec3::Zero());
  EXPECT_EQ(learner != nullptr ? learner->rowsLearnt() : 0u, 1u);
  EXPECT_NEAR(noise.tdoaExcessCorrection(m), 0.4, 1e-9);

  graph.tdoa_gap_excess.enabled = false;
  const MeasurementNoise off(anchors, graph, DynamicCovarianceOptions());
  EXPECT_EQ(off.tdoaGapExcess(), nullptr);
  EXPECT_EQ(off.tdoaExcessCorrection(m), 0.0);
  graph.tdoa_gap_excess.enabled = true;
  graph.tdoa_nlos_indicator = false;  // the gaps are not to be read
  const MeasurementNoise blind(anchors, graph, DynamicCovarianceOptions());
  EXPECT_EQ(blind.tdoaGapExcess(), nullptr);

  // The EKF goes without it, whatever the graph parameters say.
  graph.tdoa_nlos_indicator = true;
  const EkfEstimator ekf(anchors, graph, EkfParams());
  EXPECT_EQ(ekf.measurementNoise().tdoaGapExcess(), nullptr);
}

}  // namespace
}  // namespace rilo
