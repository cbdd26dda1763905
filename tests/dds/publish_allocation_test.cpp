// The publish path must not allocate. This TU replaces the global operator
// new/delete (C++ allocations: our wrapper, Eigen, libstdc++) and interposes
// malloc/calloc/realloc/free (everything, including Cyclone's C code) with
// counters that count only on the thread that opened an AllocationWindow.
//
// Asserted: no operator new at all, and no malloc in our own code (the fill
// functions and the publisher's checks, measured without dds_write). Cyclone's
// dds_write is measured and printed; it is not ours to assert on.
#include <gtest/gtest.h>
#include <pthread.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <random>
#include <utility>
#include <vector>

#include "dds/conversions.h"
#include "dds/publisher.h"
#include "dds/subscriber.h"
#include "dds_test_support.h"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define RILO_COUNT_ALLOCATIONS 0  // sanitizers own malloc and operator new (an interposed malloc crashes TSan at start)
#else
#define RILO_COUNT_ALLOCATIONS 1
#endif

namespace {

std::atomic<bool> g_counting{false};
std::atomic<pthread_t> g_counting_thread{};
std::atomic<std::uint64_t> g_news{0};
std::atomic<std::uint64_t> g_mallocs{0};
std::atomic<std::uint64_t> g_reallocs{0};

// pthread_self() only reads the thread pointer: safe inside malloc, even
// before a new thread's TLS is set up.
inline bool countingHere() noexcept {
  return g_counting.load(std::memory_order_relaxed) &&
         pthread_equal(pthread_self(), g_counting_thread.load(std::memory_order_relaxed)) != 0;
}

struct Counts {
  std::uint64_t news = 0;
  std::uint64_t mallocs = 0;   // malloc + calloc, including the malloc behind each operator new
  std::uint64_t reallocs = 0;
};

class AllocationWindow {
 public:
  AllocationWindow() noexcept {
    g_news = 0;
    g_mallocs = 0;
    g_reallocs = 0;
    g_counting_thread = pthread_self();
    g_counting = true;
  }
  ~AllocationWindow() { g_counting = false; }
  AllocationWindow(const AllocationWindow&) = delete;
  AllocationWindow& operator=(const AllocationWindow&) = delete;
  Counts counts() const noexcept { return {g_news.load(), g_mallocs.load(), g_reallocs.load()}; }
};

}  // namespace

#if RILO_COUNT_ALLOCATIONS
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void __libc_free(void* p);

// Interposed for the whole test binary (the executable's definitions win over
// libc's for every shared library, Cyclone included); all delegate to glibc.
void* malloc(std::size_t size) noexcept {
  if (countingHere()) g_mallocs.fetch_add(1, std::memory_order_relaxed);
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  if (countingHere()) g_mallocs.fetch_add(1, std::memory_order_relaxed);
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) noexcept {
  if (countingHere()) g_reallocs.fetch_add(1, std::memory_order_relaxed);
  return __libc_realloc(p, size);
}
void free(void* p) noexcept { __libc_free(p); }
}

void* operator new(std::size_t size) {
  if (countingHere()) g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return ::operator new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  if (countingHere()) g_news.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t& tag) noexcept { return ::operator new(size, tag); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
#endif

namespace rilo::dds {
namespace {

using namespace std::chrono_literals;

constexpr int kWarmUp = 100;
constexpr int kWrites = 1000;
constexpr std::int64_t kImuPeriodNs = 5'000'000;  // 200 Hz

class DdsPublishAllocation : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!RILO_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under sanitizers";
    // The counters must see this thread's allocations.
    {
      AllocationWindow w;
      void* p = std::malloc(16);
      std::free(p);
      delete new int(1);
      const Counts c = w.counts();
      ASSERT_EQ(c.news, 1u);
      ASSERT_EQ(c.mallocs, 2u);
    }
  }
};

TEST_F(DdsPublishAllocation, OurFillAndChecksNeverAllocate) {
  std::mt19937 rng(31);
  NavigationState state = testing::randomState(rng, 1'000'000'000);
  ServiceStatus status = testing::sampleStatus(1'000'000'000);
  nav_msgs_msg_dds__Odometry_ odometry{};
  geometry_msgs_msg_dds__PoseWithCovarianceStamped_ pose{};
  rilo_msg_dds__Status_ status_msg{};
  geometry_msgs_msg_dds__TransformStamped_ transform{};
  AllocationWindow w;
  for (int i = 0; i < kWrites; ++i) {
    state.t_ns += kImuPeriodNs;
    fillOdometry(state, odometry);
    fillPose(state, pose);
    fillTransform(state, transform, 1'000);
    status.t_ns = state.t_ns;
    fillStatus(status, status_msg);
  }
  const Counts c = w.counts();
  EXPECT_EQ(c.news, 0u);
  EXPECT_EQ(c.mallocs, 0u);
  EXPECT_EQ(c.reallocs, 0u);
  EXPECT_EQ(odometry.header.stamp.sec, 6);  // 1 s + 1000 * 5 ms
}

TEST_F(DdsPublishAllocation, RejectedSamplesNeverAllocate) {
  Participant participant(testing::loopbackOptions());
  PublisherOptions po;
  po.topics = testing::uniqueTopicNames("alloc_rejected");
  Publisher pub(participant, po);
  std::mt19937 rng(32);
  NavigationState state = testing::randomState(rng, 1);
  state.valid = false;
  AllocationWindow w;
  for (int i = 0; i < kWrites; ++i) {
    const WriteStatus ws = pub.publishOdometry(state);
    if (ws.ok() || ws.text() == nullptr) ADD_FAILURE();
  }
  const Counts c = w.counts();
  EXPECT_EQ(c.news, 0u);
  EXPECT_EQ(c.mallocs, 0u);
  EXPECT_EQ(c.reallocs, 0u);
  EXPECT_EQ(c.reallocs, 0u);
}

enum class Writes { kOdometry, kPose, kTransform, kRanges, kStatus };

/// Publishes kWarmUp then kWrites (counted) samples of one topic.
Counts countWrites(Publisher& pub, Writes what, std::mt19937& rng) {
  NavigationState state = testing::randomState(rng, 1'000'000'000);
  ServiceStatus status = testing::sampleStatus(1'000'000'000);
  const std::vector<RangeReading> ranges(8, RangeReading{2, 5.0, 4.9, 0.1, 0.9, false});  // an epoch of 8 anchors
  const auto publish = [&]() noexcept {
    state.t_ns += kImuPeriodNs;
    status.t_ns = state.t_ns;
    switch (what) {
      case Writes::kOdometry: return pub.publishOdometry(state).ok();
      case Writes::kPose: return pub.publishPose(state).ok();
      case Writes::kTransform: return pub.publishTransform(state).ok();
      case Writes::kRanges: return pub.publishRanges(state.t_ns, ranges).ok();
      case Writes::kStatus: break;
    }
    return pub.publishStatus(status).ok();
  };
  bool all_ok = true;
  for (int i = 0; i < kWarmUp; ++i) all_ok = publish() && all_ok;
  Counts c;
  {
    AllocationWindow w;
    for (int i = 0; i < kWrites; ++i) all_ok = publish() && all_ok;
    c = w.counts();
  }
  EXPECT_TRUE(all_ok);
  return c;
}

void report(const char* what, const Counts& c) {
  std::printf("[ alloc    ] %d %s: %llu operator new, %llu malloc/calloc, %llu realloc\n", kWrites, what,
              static_cast<unsigned long long>(c.news), static_cast<unsigned long long>(c.mallocs),
              static_cast<unsigned long long>(c.reallocs));
}

// No operator new anywhere on the path. Cyclone 0.10.2's dds_write itself
// allocates the serialized sample (one malloc and one realloc of its buffer
// per write, any topic, with or without readers); printed, not asserted.
TEST_F(DdsPublishAllocation, OdometryWithoutSubscriber) {
  Participant participant(testing::loopbackOptions());
  PublisherOptions po;
  po.topics = testing::uniqueTopicNames("alloc_nosub");
  Publisher pub(participant, po);
  std::mt19937 rng(33);
  const Counts c = countWrites(pub, Writes::kOdometry, rng);
  EXPECT_EQ(c.news, 0u);
  report("odometry writes, no subscriber", c);
}

TEST_F(DdsPublishAllocation, AllTopicsWithInProcessSubscriber) {
  Participant pub_participant(testing::loopbackOptions());
  Participant sub_participant(testing::loopbackOptions());
  PublisherOptions po;
  po.topics = testing::uniqueTopicNames("alloc_sub");
  po.stamp_clock = StampClock::kMonotonic;  // the stamp is checked below
  Publisher pub(pub_participant, po);
  SubscriberOptions so;
  so.topics = po.topics;
  so.tf = true;
  so.ranges = true;
  so.odometry_depth = 1;  // the reader keeps one sample: steady state from the first write
  Subscriber sub(sub_participant, so);
  for (TopicKind kind : {TopicKind::kOdometry, TopicKind::kPose, TopicKind::kTf, TopicKind::kRanges, TopicKind::kStatus}) {
    ASSERT_TRUE(pub.waitForSubscribers(kind, 1, testing::kMatchTimeout));
  }
  std::mt19937 rng(34);
  for (const auto& [what, label] : {std::pair{Writes::kOdometry, "odometry writes, in-process subscriber"},
                                    std::pair{Writes::kPose, "pose writes, in-process subscriber"},
                                    std::pair{Writes::kTransform, "TF writes, in-process subscriber"},
                                    std::pair{Writes::kRanges, "ranges writes (8 per epoch), in-process subscriber"},
                                    std::pair{Writes::kStatus, "status writes, in-process subscriber"}}) {
    const Counts c = countWrites(pub, what, rng);
    EXPECT_EQ(c.news, 0u) << label;
    report(label, c);
  }

  std::vector<OdometryMessage> got;
  sub.takeOdometry(got);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].stamp_ns, 1'000'000'000 + (kWarmUp + kWrites) * kImuPeriodNs);
}

}  // namespace
}  // namespace rilo::dds
