// The Localizer with rilod's real init runner: attempts on the InitWorker
// thread while this thread keeps feeding samples as fast as it can (the
// attempts lag the data by however long they take). It must start, catch
// up and track about as well as inline; under ThreadSanitizer (RILO_TSAN)
// this is the check that the copy hand-off shares nothing with the worker.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>

#include "estimation/tracking/localizer.h"
#include "runtime/init_worker.h"
#include "sim/range_imu_scenario.h"
#include "support/online_run.h"

namespace rilo {
namespace {

struct Tracked {
  int updates = 0;
  double mean_error_m = 0.0;
};

/// Feeds in time order; with `speed` > 0, no faster than that many data
/// seconds per wall second (as rilod's replay), else as fast as it can.
Tracked feed(const sim::Scenario& s, Localizer& localizer, double speed) {
  Tracked out;
  double sum = 0.0;
  std::size_t i = 0, r = 0;
  const auto wall0 = std::chrono::steady_clock::now();
  const std::int64_t t0 = s.imu.front().t_ns;
  while (i < s.imu.size() || r < s.ranges.size()) {
    std::int64_t t_ns = 0;
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      t_ns = s.ranges[r].t_ns;
      localizer.addRange(s.ranges[r++]);
    } else {
      t_ns = s.imu[i].t_ns;
      localizer.addImu(s.imu[i++]);
    }
    if (speed > 0.0) {
      std::this_thread::sleep_until(wall0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                std::chrono::duration<double>(static_cast<double>(t_ns - t0) * 1e-9 / speed)));
    }
    if (localizer.process() > 0 && localizer.tracking()) {
      sum += (localizer.latest().T_w_b.p - s.truthAt(localizer.latest().t_ns).T_w_b.p).norm();
      ++out.updates;
    }
  }
  localizer.finish();
  // As rilod: what finish() let through (an attempt it took starts the tracker there).
  while (localizer.process() > 0) {
  }
  if (out.updates > 0) out.mean_error_m = sum / out.updates;
  return out;
}

TEST(LocalizerOnInitWorker, StartsCatchesUpAndTracksLikeInline) {
  sim::ScenarioParams sp;
  sp.duration_s = 60.0;
  sp.seed = 3;
  const sim::Scenario s = sim::simulateScenario(sp);
  const LocalizerParams p = testing::localizerParamsFor(s);

  Localizer inline_localizer(s.p_w_anchors, p);
  const Tracked inline_run = feed(s, inline_localizer, 0.0);
  ASSERT_TRUE(inline_localizer.tracking());

  Localizer localizer(s.p_w_anchors, p);
  auto worker = std::make_unique<InitWorker>("test-init");
  const InitWorker& w = *worker;
  localizer.setInitRunner(std::move(worker));
  const Tracked run = feed(s, localizer, 10.0);
  ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
  EXPECT_GE(w.attemptsRun(), 1u);
  EXPECT_EQ(static_cast<int>(w.attemptsRun()), localizer.initStatus().attempts) << "each attempt adopted once";
  EXPECT_EQ(localizer.reinitializations(), 0u) << localizer.lastFailure();
  // Caught up to the end of the data, on the walk.
  EXPECT_GT(localizer.latest().t_ns, s.imu.back().t_ns - 500'000'000);
  EXPECT_LT((localizer.latest().T_w_b.p - s.truthAt(localizer.latest().t_ns).T_w_b.p).norm(), 1.0);
  // How many updates this thread saw depends on how long the attempts took
  // (a sanitizer build: seconds); those it saw track as inline.
  std::printf("%d updates seen (inline %d), mean error %.3f m (inline %.3f m)\n", run.updates, inline_run.updates,
              run.mean_error_m, inline_run.mean_error_m);
  if (run.updates > 50) {
    EXPECT_LT(run.mean_error_m, std::max(1.0, inline_run.mean_error_m + 0.2));
  }
}

}  // namespace
}  // namespace rilo
