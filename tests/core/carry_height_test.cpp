#include "estimation/measurements/carry_height.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace rilo {
namespace {

constexpr std::int64_t kSecond = 1'000'000'000;

HeightBand band(double memory_s = 120.0) {
  HeightBand b;  // 0.9-1.9 m above a floor at 0
  b.carry_memory_s = memory_s;
  return b;
}

constexpr bool kLearn = true;

TEST(CarryHeight, StartsAtTheBandsMiddle) {
  const CarryHeight h(band(), kLearn);
  EXPECT_DOUBLE_EQ(h.heightM(), 1.4);
  EXPECT_EQ(h.evidence(), 0.0);
}

TEST(CarryHeight, WithoutLearningStaysAtTheMiddle) {
  CarryHeight h(band(), false);
  h.addEvidence(1, 100.0);
  h.notePostFit(1, kSecond, 1.7);
  EXPECT_DOUBLE_EQ(h.heightM(), 1.4);
}

TEST(CarryHeight, MovesTowardsHeightsWeightedByTheirEvidence) {
  CarryHeight h(band(), kLearn);
  // Prior sigma a quarter of the band's 1 m width: information 16 / m^2.
  h.addEvidence(1, 16.0);
  h.notePostFit(1, kSecond, 1.7);
  EXPECT_NEAR(h.heightM(), 0.5 * (1.4 + 1.7), 1e-12);
  // A state without evidence (at the same time: nothing fades) moves nothing.
  h.notePostFit(2, kSecond, 0.95);
  EXPECT_NEAR(h.heightM(), 1.55, 1e-12);
  // Much evidence at 1.7 m: close to it.
  for (std::uint64_t i = 3; i < 100; ++i) {
    h.addEvidence(i, 16.0);
    h.notePostFit(i, static_cast<std::int64_t>(i) * kSecond / 40 + 2 * kSecond, 1.7);
  }
  EXPECT_NEAR(h.heightM(), 1.7, 0.01);
}

TEST(CarryHeight, EvidenceOfOneStateAddsUpAndWaitsForItsPostFit) {
  CarryHeight h(band(), kLearn);
  h.addEvidence(5, 8.0);
  h.addEvidence(5, 8.0);
  h.notePostFit(4, kSecond, 1.8);  // an earlier state: no evidence of its own
  EXPECT_DOUBLE_EQ(h.heightM(), 1.4);
  h.notePostFit(5, kSecond, 1.8);
  EXPECT_NEAR(h.heightM(), 1.6, 1e-12);
  EXPECT_NEAR(h.evidence(), 16.0, 1e-12);
}

TEST(CarryHeight, StatesSkippedWithoutPostFitAreDropped) {
  CarryHeight h(band(), kLearn);
  h.addEvidence(1, 16.0);
  h.addEvidence(2, 16.0);
  h.notePostFit(2, kSecond, 1.8);  // state 1's evidence has no height: dropped
  EXPECT_NEAR(h.heightM(), 1.6, 1e-12);
  h.notePostFit(1, kSecond, 0.9);  // too late: nothing pending for it
  EXPECT_NEAR(h.heightM(), 1.6, 1e-12);
}

TEST(CarryHeight, HeightsOutsideTheBandCountAtItsEdge) {
  CarryHeight h(band(), kLearn);
  h.addEvidence(1, 16.0);
  h.notePostFit(1, kSecond, 5.0);
  EXPECT_NEAR(h.heightM(), 0.5 * (1.4 + 1.9), 1e-12);
}

TEST(CarryHeight, OldEvidenceFadesBackToTheMiddle) {
  CarryHeight h(band(10.0), kLearn);
  h.addEvidence(1, 1600.0);
  h.notePostFit(1, kSecond, 1.8);
  EXPECT_NEAR(h.heightM(), 1.8, 0.01);
  // 100 s (ten memories) later, a state without evidence: the old evidence
  // has faded to e^-10 of itself.
  h.notePostFit(2, 101 * kSecond, 1.9);
  EXPECT_NEAR(h.heightM(), 1.4, 0.01);
  EXPECT_LT(h.evidence(), 0.1);
}

TEST(CarryHeight, BadEvidenceIsIgnored) {
  CarryHeight h(band(), kLearn);
  h.addEvidence(1, -3.0);
  h.addEvidence(1, std::nan(""));
  h.notePostFit(1, kSecond, 1.8);
  h.addEvidence(2, 16.0);
  h.notePostFit(2, 2 * kSecond, std::nan(""));
  EXPECT_DOUBLE_EQ(h.heightM(), 1.4);
}

TEST(CarryHeight, NonPositiveMemoryThrows) {
  EXPECT_THROW(CarryHeight(band(0.0), kLearn), std::invalid_argument);
  EXPECT_THROW(CarryHeight(band(-1.0), kLearn), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
