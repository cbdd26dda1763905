// The IMU-rate path never allocates: queues, seqlock hand-over and the output
// predictor run 10k times each under an AllocationCounter that sees every
// operator new/delete and (outside sanitizer builds) every malloc/free.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <vector>

#include "runtime/latest_value.h"
#include "runtime/output_predictor.h"
#include "runtime/spsc_queue.h"
#include "runtime/support/alloc_counter.h"
#include "runtime/support/analytic_motion.h"

namespace rilo {
namespace {

using testing::AllocationCounter;

// Keeps the compiler from eliding an allocation whose result is unused.
void escape(void* p) { asm volatile("" : : "g"(p) : "memory"); }

constexpr int kIterations = 10'000;

TEST(NoAllocation, CounterSeesOperatorNew) {
  std::uint64_t news = 0, deletes = 0;
  {
    AllocationCounter counter;
    auto p = std::make_unique<double>(1.0);
    escape(p.get());
    std::vector<int> v(100);
    escape(v.data());
    v.clear();
    v.shrink_to_fit();
    p.reset();
    news = counter.allocations();
    deletes = counter.deallocations();
  }
  EXPECT_EQ(news, 2u);
  EXPECT_EQ(deletes, 2u);
}

TEST(NoAllocation, CounterSeesMalloc) {
  if (!testing::countsMalloc()) GTEST_SKIP() << "malloc is not interposed in sanitizer builds";
  std::uint64_t mallocs = 0;
  {
    AllocationCounter counter;
    void* m = std::malloc(64);
    escape(m);
    std::free(m);
    Eigen::MatrixXd dynamic(8, 8);  // Eigen allocates with malloc, not operator new
    escape(dynamic.data());
    mallocs = counter.allocations();
  }
  EXPECT_EQ(mallocs, 2u);
}

TEST(NoAllocation, SpscPushPop) {
  SpscQueue<ImuSample> q(64);
  std::uint64_t allocations = 0;
  std::int64_t checksum = 0;
  {
    AllocationCounter counter;
    ImuSample s, out;
    for (int i = 0; i < kIterations; ++i) {
      s.t_ns = i;
      q.tryPush(s);
      if (i % 3 != 0) {
        q.tryPop(out);
        checksum += out.t_ns;
      }
    }
    allocations = counter.allocations() + counter.deallocations();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_GT(checksum, 0);
}

TEST(NoAllocation, SeqlockWriteRead) {
  LatestValue<NavigationState> latest;
  std::uint64_t allocations = 0;
  std::int64_t last_t = 0;
  {
    AllocationCounter counter;
    NavigationState s, out;
    std::uint64_t seen = 0;
    for (int i = 0; i < kIterations; ++i) {
      s.t_ns = i + 1;
      latest.write(s);
      if (latest.readIfNewer(out, seen)) last_t = out.t_ns;
    }
    allocations = counter.allocations() + counter.deallocations();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(last_t, kIterations);
}

TEST(NoAllocation, OutputPredictorImuAndSmoothed) {
  OutputPredictor pred;  // allocates its ring here, before counting
  constexpr std::int64_t kPeriodNs = 5'000'000;
  // Samples and smoothed states computed up front: the analytic motion is not under test.
  std::vector<ImuSample> samples;
  for (int i = 0; i < kIterations; ++i) samples.push_back(testing::idealImuAt(i * kPeriodNs));
  std::vector<NavigationState> smoothed;
  for (int i = 0; i < kIterations; i += 40) smoothed.push_back(testing::truthAt((i - 30) * kPeriodNs));
  std::uint64_t allocations = 0;
  bool valid = false;
  {
    AllocationCounter counter;
    for (int i = 0; i < kIterations; ++i) {
      pred.onImu(samples[static_cast<std::size_t>(i)]);
      // Every 40 samples (5 Hz) a smoothed state 30 samples old: re-integrates 30 samples.
      if (i % 40 == 0) pred.onSmoothed(smoothed[static_cast<std::size_t>(i / 40)]);
    }
    valid = pred.state().valid;
    allocations = counter.allocations() + counter.deallocations();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_TRUE(valid);
  EXPECT_EQ(pred.state().t_ns, (kIterations - 1) * kPeriodNs);
}

}  // namespace
}  // namespace rilo
