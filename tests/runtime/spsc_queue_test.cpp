#include "runtime/spsc_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <thread>

#include "sensors/samples.h"

namespace rilo {
namespace {

// A sequenced item whose payload is derived from the sequence number, so a
// slot read while half-written (or a stale slot) is detected.
struct Item {
  std::uint64_t seq = 0;
  std::uint64_t check = 0;
  double payload[6] = {};
};
Item makeItem(std::uint64_t seq) {
  Item it;
  it.seq = seq;
  it.check = seq * 0x9E3779B97F4A7C15ULL;
  for (int i = 0; i < 6; ++i) it.payload[i] = static_cast<double>(seq) + i;
  return it;
}
bool consistent(const Item& it) {
  if (it.check != it.seq * 0x9E3779B97F4A7C15ULL) return false;
  for (int i = 0; i < 6; ++i) {
    if (it.payload[i] != static_cast<double>(it.seq) + i) return false;
  }
  return true;
}

TEST(SpscQueue, CapacityRoundsUpToPowerOfTwo) {
  EXPECT_EQ(SpscQueue<int>(1).capacity(), 1u);
  EXPECT_EQ(SpscQueue<int>(3).capacity(), 4u);
  EXPECT_EQ(SpscQueue<int>(1000).capacity(), 1024u);
  EXPECT_EQ(SpscQueue<int>(1024).capacity(), 1024u);
  EXPECT_THROW(SpscQueue<int>(0), std::invalid_argument);
  EXPECT_THROW(SpscQueue<int>(SpscQueue<int>::kMaxCapacity + 1), std::invalid_argument);
}

TEST(SpscQueue, IndicesLiveOnSeparateCacheLines) {
  EXPECT_EQ(alignof(SpscQueue<int>), kCacheLineBytes);
  EXPECT_EQ(sizeof(SpscQueue<int>) % kCacheLineBytes, 0u);
  EXPECT_GE(sizeof(SpscQueue<int>), 3 * kCacheLineBytes);  // constants, producer line, consumer line
}

TEST(SpscQueue, FullRejectsPushAndEmptyRejectsPop) {
  SpscQueue<int> q(4);
  int out = -1;
  EXPECT_FALSE(q.tryPop(out));
  EXPECT_EQ(out, -1);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(q.tryPush(i));
  EXPECT_FALSE(q.tryPush(99));
  EXPECT_EQ(q.sizeApprox(), 4u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(q.tryPop(out));
    EXPECT_EQ(out, i);
  }
  EXPECT_FALSE(q.tryPop(out));
  EXPECT_TRUE(q.emptyApprox());
}

TEST(SpscQueue, FifoOrderAcrossManyWraps) {
  SpscQueue<std::uint64_t> q(8);
  std::uint64_t next_in = 0, next_out = 0;
  for (int round = 0; round < 1000; ++round) {
    const int n_push = 1 + round % 8;
    for (int i = 0; i < n_push; ++i) ASSERT_TRUE(q.tryPush(next_in++));
    const int n_pop = round % 3 == 0 ? n_push : static_cast<int>(q.sizeApprox());
    for (int i = 0; i < n_pop; ++i) {
      std::uint64_t v = 0;
      ASSERT_TRUE(q.tryPop(v));
      ASSERT_EQ(v, next_out++);
    }
  }
  EXPECT_EQ(q.sizeApprox(), next_in - next_out);
}

TEST(SpscQueue, CarriesImuSamples) {
  SpscQueue<ImuSample> q(16);
  ImuSample s;
  s.t_ns = 42;
  s.gyro_rad_s = Eigen::Vector3d(1, 2, 3);
  s.accel_m_s2 = Eigen::Vector3d(4, 5, 6);
  ASSERT_TRUE(q.tryPush(s));
  ImuSample out;
  ASSERT_TRUE(q.tryPop(out));
  EXPECT_EQ(out.t_ns, 42);
  EXPECT_EQ(out.gyro_rad_s, s.gyro_rad_s);
  EXPECT_EQ(out.accel_m_s2, s.accel_m_s2);
}

constexpr std::uint64_t kStressItems = 1'000'000;

// Producer never waits: a full queue drops the item and counts it. Every item
// the consumer sees is intact, in order, without duplicates, and received plus
// dropped accounts for every item.
TEST(SpscQueueStress, DropOnFullLosesOnlyCountedItems) {
  SpscQueue<Item> q(256);
  std::uint64_t overflows = 0;  // written by the producer, read after join
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (std::uint64_t seq = 0; seq < kStressItems; ++seq) {
      if (!q.tryPush(makeItem(seq))) ++overflows;
    }
    done.store(true, std::memory_order_release);  // every push happens-before this
  });
  std::uint64_t received = 0, corrupt = 0, disorder = 0;
  std::int64_t last = -1;
  for (;;) {
    // Read the flag before popping: once it is set, an empty pop means drained.
    const bool finished = done.load(std::memory_order_acquire);
    Item it;
    if (q.tryPop(it)) {
      ++received;
      if (!consistent(it)) ++corrupt;
      if (static_cast<std::int64_t>(it.seq) <= last) ++disorder;
      last = static_cast<std::int64_t>(it.seq);
    } else if (finished) {
      break;
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  EXPECT_EQ(corrupt, 0u);
  EXPECT_EQ(disorder, 0u);
  EXPECT_EQ(received + overflows, kStressItems);
  EXPECT_GT(received, 0u);
}

// Producer retries when full: all items arrive, exactly once, in order.
TEST(SpscQueueStress, RetryOnFullDeliversEverythingInOrder) {
  SpscQueue<Item> q(1024);
  std::thread producer([&] {
    for (std::uint64_t seq = 0; seq < kStressItems; ++seq) {
      const Item it = makeItem(seq);
      while (!q.tryPush(it)) std::this_thread::yield();
    }
  });
  std::uint64_t expected = 0, errors = 0;
  while (expected < kStressItems) {
    Item it;
    if (!q.tryPop(it)) {
      std::this_thread::yield();
      continue;
    }
    if (it.seq != expected || !consistent(it)) ++errors;
    expected = it.seq + 1;
  }
  producer.join();
  Item extra;
  EXPECT_FALSE(q.tryPop(extra));
  EXPECT_EQ(errors, 0u);
  EXPECT_EQ(expected, kStressItems);
}

}  // namespace
}  // namespace rilo
