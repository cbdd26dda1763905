// NlosMemory: an anchor's last two ranges judged beyond the mixture's
// decision point flag its next range; one long range, a range that fits
// again, or judgements older than the window do not.
#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>
#include <string>

#include "estimation/measurements/nlos_memory.h"

namespace rilo {
namespace {

constexpr double kDecisionM = 0.21;
constexpr std::int64_t kMs = 1'000'000;

NlosMemory memory(double window_s = 0.5) {
  NlosMemoryParams p;
  p.window_s = window_s;
  return NlosMemory(3, kDecisionM, p);
}

TEST(NlosMemory, TwoRangesBeyondTheDecisionPointFlagTheAnchorsNext) {
  NlosMemory m = memory();
  EXPECT_TRUE(m.enabled());
  m.judged(1, 0, 0, 0.4);
  EXPECT_FALSE(m.remembersNlos(1, 0, 100 * kMs)) << "one long range is the mixture's business";
  m.judged(1, 0, 200 * kMs, 0.3);
  EXPECT_TRUE(m.remembersNlos(1, 0, 400 * kMs));
  EXPECT_FALSE(m.remembersNlos(0, 0, 400 * kMs)) << "another anchor's ranges say nothing of this one";
  EXPECT_FALSE(m.remembersNlos(2, 0, 400 * kMs));
  // Both must lie within the window before the new range.
  EXPECT_TRUE(m.remembersNlos(1, 0, 500 * kMs));
  EXPECT_FALSE(m.remembersNlos(1, 0, 501 * kMs)) << "the older one is 501 ms before";
}

TEST(NlosMemory, AtTheDecisionPointOrARangeThatFitsAgainClearsIt) {
  NlosMemory m = memory();
  m.judged(0, 0, 0, kDecisionM);  // at the point: the mixture's LOS core
  m.judged(0, 0, 100 * kMs, 1.0);
  EXPECT_FALSE(m.remembersNlos(0, 0, 150 * kMs));
  m.judged(0, 0, 200 * kMs, 0.8);
  EXPECT_TRUE(m.remembersNlos(0, 0, 250 * kMs));
  m.judged(0, 0, 300 * kMs, 0.02);  // the path is clear again
  EXPECT_FALSE(m.remembersNlos(0, 0, 350 * kMs));
  m.judged(0, 0, 400 * kMs, -0.5);  // short: never NLOS
  m.judged(0, 0, 450 * kMs, 0.5);
  EXPECT_FALSE(m.remembersNlos(0, 0, 460 * kMs));
}

// Two antennas on one body (tags.csv): the body that blocks one antenna's
// path may leave the other's clear, so each antenna has its own memory of an
// anchor, interleaved as their ranges come.
TEST(NlosMemory, EachAntennaHasItsOwnMemoryOfAnAnchor) {
  NlosMemory m = memory();
  m.judged(1, 0, 0, 0.5);   // antenna 0 blocked
  m.judged(1, 1, 10 * kMs, 0.0);  // antenna 1 clear
  m.judged(1, 0, 20 * kMs, 0.6);
  m.judged(1, 1, 30 * kMs, 0.01);
  EXPECT_TRUE(m.remembersNlos(1, 0, 40 * kMs));
  EXPECT_FALSE(m.remembersNlos(1, 1, 40 * kMs));
  EXPECT_FALSE(m.remembersNlos(1, 2, 40 * kMs)) << "an antenna never judged";
  // Antenna 1's ranges long now too; many judgements later the ring still
  // holds each antenna's last two.
  for (int k = 0; k < 20; ++k) m.judged(1, k % 2 == 0 ? 1u : 0u, (50 + 10 * k) * kMs, 0.4);
  EXPECT_TRUE(m.remembersNlos(1, 1, 260 * kMs));
  EXPECT_TRUE(m.remembersNlos(1, 0, 260 * kMs));
}

TEST(NlosMemory, ResetForgetsAndUnknownAnchorsAreIgnored) {
  NlosMemory m = memory();
  m.judged(2, 0, 0, 0.5);
  m.judged(2, 0, 10 * kMs, 0.5);
  m.judged(7, 0, 10 * kMs, 0.5);  // no such anchor: ignored, no crash
  EXPECT_TRUE(m.remembersNlos(2, 0, 20 * kMs));
  EXPECT_FALSE(m.remembersNlos(7, 0, 20 * kMs));
  m.reset();
  EXPECT_FALSE(m.remembersNlos(2, 0, 20 * kMs));
}

TEST(NlosMemory, OffWithoutADecisionPointOrAWindow) {
  for (NlosMemory m : {NlosMemory(3, std::numeric_limits<double>::quiet_NaN(), {}),
                       NlosMemory(3, std::numeric_limits<double>::infinity(), {}), memory(0.0)}) {
    EXPECT_FALSE(m.enabled());
    m.judged(0, 0, 0, 5.0);
    m.judged(0, 0, 1 * kMs, 5.0);
    EXPECT_FALSE(m.remembersNlos(0, 0, 2 * kMs));
  }
}

TEST(NlosMemory, BadParametersNameTheField) {
  NlosMemoryParams p;
  p.window_s = -0.1;
  try {
    NlosMemory(3, kDecisionM, p);
    FAIL() << "a negative window must throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("window_s"), std::string::npos) << e.what();
  }
  p.window_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(NlosMemory(3, kDecisionM, p), std::invalid_argument);
  try {
    NlosMemory(3, -0.2, {});
    FAIL() << "a negative decision point must throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("decision_point_m"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rilo
