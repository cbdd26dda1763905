// The Localizer's windowed rejection-share rule in isolation.
#include "estimation/tracking/rejection_window.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace rilo {
namespace {

TEST(RejectionWindow, WaitsUntilTheWindowIsFull) {
  RejectionWindow w(10, 0.5);
  for (int k = 0; k < 9; ++k) EXPECT_FALSE(w.note(false)) << k;  // 9 of 9 rejected, but only 9 seen
  EXPECT_EQ(w.filled(), 9);
  EXPECT_TRUE(w.note(false));  // full: 10 of 10 > 5
  EXPECT_EQ(w.rejected(), 10);
}

TEST(RejectionWindow, ShareAtTheLimitIsHealthyAboveItFails) {
  RejectionWindow w(10, 0.5);
  // Alternating: 5 of 10 rejected, exactly the limit, for a long time.
  for (int k = 0; k < 100; ++k) ASSERT_FALSE(w.note(k % 2 == 0)) << k;
  EXPECT_EQ(w.rejected(), 5);
  EXPECT_DOUBLE_EQ(w.share(), 0.5);
  // One more rejection in place of an acceptance: the oldest entry (k = 90,
  // accepted) leaves, 6 of 10 rejected.
  EXPECT_TRUE(w.note(false));
  EXPECT_EQ(w.rejected(), 6);
}

TEST(RejectionWindow, LuckyAcceptancesDoNotHideAMostlyRejectingRun) {
  // What max_consecutive_rejections misses: one accepted update in three.
  RejectionWindow w(30, 0.5);
  int first_verdict = -1;
  for (int k = 0; k < 100 && first_verdict < 0; ++k) {
    if (w.note(k % 3 == 0)) first_verdict = k;
  }
  EXPECT_EQ(first_verdict, 29);  // the first full window: 20 of 30 rejected
}

TEST(RejectionWindow, OldRejectionsLeaveTheWindow) {
  RejectionWindow w(20, 0.25);
  for (int k = 0; k < 5; ++k) EXPECT_FALSE(w.note(false));  // a burst of 5 (= the limit) at the start
  for (int k = 0; k < 15; ++k) EXPECT_FALSE(w.note(true));
  EXPECT_EQ(w.rejected(), 5);
  for (int k = 0; k < 5; ++k) EXPECT_FALSE(w.note(true));  // the burst leaves
  EXPECT_EQ(w.rejected(), 0);
  for (int k = 0; k < 5; ++k) EXPECT_FALSE(w.note(false));
  EXPECT_TRUE(w.note(false));  // 6 > 5
}

TEST(RejectionWindow, ResetForgetsEverything) {
  RejectionWindow w(4, 0.5);
  for (int k = 0; k < 3; ++k) w.note(false);
  w.reset();
  EXPECT_EQ(w.filled(), 0);
  EXPECT_EQ(w.rejected(), 0);
  for (int k = 0; k < 3; ++k) EXPECT_FALSE(w.note(false));
  EXPECT_TRUE(w.note(false));
}

TEST(RejectionWindow, ZeroShareFailsOnAnyRejectionInAFullWindow) {
  RejectionWindow w(3, 0.0);
  EXPECT_FALSE(w.note(true));
  EXPECT_FALSE(w.note(true));
  EXPECT_FALSE(w.note(true));
  EXPECT_TRUE(w.note(false));
}

TEST(RejectionWindow, RejectsBadParameters) {
  EXPECT_THROW(RejectionWindow(0, 0.5), std::invalid_argument);
  EXPECT_THROW(RejectionWindow(10, 1.0), std::invalid_argument);
  EXPECT_THROW(RejectionWindow(10, -0.1), std::invalid_argument);
  try {
    RejectionWindow(10, 2.0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_share"), std::string::npos);
  }
}

}  // namespace
}  // namespace rilo
