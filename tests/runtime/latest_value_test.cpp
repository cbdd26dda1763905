#include "runtime/latest_value.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include "runtime/navigation_state.h"
#include "runtime/service_status.h"

namespace rilo {
namespace {

// 32 words written one at a time by the seqlock: a torn copy mixes two writes
// and fails the checksum.
struct Checked {
  std::uint64_t seq = 0;
  std::array<std::uint64_t, 30> words{};
  std::uint64_t checksum = 0;
};
std::uint64_t mix(std::uint64_t seq, std::uint64_t i) { return (seq + 1) * 0x9E3779B97F4A7C15ULL ^ (i << 32 | i); }
Checked makeChecked(std::uint64_t seq) {
  Checked c;
  c.seq = seq;
  c.checksum = seq;
  for (std::uint64_t i = 0; i < c.words.size(); ++i) {
    c.words[i] = mix(seq, i);
    c.checksum ^= c.words[i] * (i + 1);
  }
  return c;
}
bool intact(const Checked& c) {
  std::uint64_t sum = c.seq;
  for (std::uint64_t i = 0; i < c.words.size(); ++i) {
    if (c.words[i] != mix(c.seq, i)) return false;
    sum ^= c.words[i] * (i + 1);
  }
  return sum == c.checksum;
}

// A NavigationState whose every field is a function of k.
NavigationState makeNav(std::int64_t k) {
  NavigationState s;
  const double x = static_cast<double>(k);
  s.t_ns = k;
  s.q_w_b = Eigen::Quaterniond(Eigen::AngleAxisd(1e-3 * x, Eigen::Vector3d::UnitZ()));
  s.p_w_b = Eigen::Vector3d(x, 2 * x, 3 * x);
  s.v_w_b = Eigen::Vector3d(-x, x, 0.5 * x);
  s.omega_b.setConstant(x);
  s.accel_bias_m_s2.setConstant(2 * x);
  s.gyro_bias_rad_s.setConstant(3 * x);
  s.pose_covariance = Eigen::Matrix<double, 6, 6>::Constant(x);
  s.twist_covariance = Eigen::Matrix<double, 6, 6>::Constant(-x);
  s.valid = (k % 2) == 0;
  return s;
}
bool matchesNav(const NavigationState& s) {
  const NavigationState e = makeNav(s.t_ns);
  return s.q_w_b.coeffs() == e.q_w_b.coeffs() && s.p_w_b == e.p_w_b && s.v_w_b == e.v_w_b &&
         s.omega_b == e.omega_b && s.accel_bias_m_s2 == e.accel_bias_m_s2 && s.gyro_bias_rad_s == e.gyro_bias_rad_s &&
         s.pose_covariance == e.pose_covariance && s.twist_covariance == e.twist_covariance && s.valid == e.valid;
}

TEST(LatestValue, StartsWithInitialValueAtVersionZero) {
  LatestValue<Checked> v(makeChecked(7));
  EXPECT_EQ(v.version(), 0u);
  std::uint64_t version = 99;
  const Checked c = v.read(&version);
  EXPECT_EQ(version, 0u);
  EXPECT_EQ(c.seq, 7u);
  EXPECT_TRUE(intact(c));
}

TEST(LatestValue, ReadReturnsTheLastWriteAndItsVersion) {
  LatestValue<Checked> v;
  for (std::uint64_t k = 1; k <= 5; ++k) v.write(makeChecked(k));
  std::uint64_t version = 0;
  Checked c;
  ASSERT_TRUE(v.tryRead(c, &version));
  EXPECT_EQ(version, 5u);
  EXPECT_EQ(c.seq, 5u);
  EXPECT_TRUE(intact(c));
}

TEST(LatestValue, ZeroAttemptsLeaveOutputUntouched) {
  LatestValue<Checked> v(makeChecked(1));
  Checked c = makeChecked(3);
  EXPECT_FALSE(v.tryRead(c, nullptr, 0));
  EXPECT_EQ(c.seq, 3u);
}

TEST(LatestValue, ReadIfNewerCopiesEachVersionOnce) {
  LatestValue<Checked> v;
  std::uint64_t seen = 0;
  Checked c;
  EXPECT_FALSE(v.readIfNewer(c, seen));
  v.write(makeChecked(10));
  ASSERT_TRUE(v.readIfNewer(c, seen));
  EXPECT_EQ(seen, 1u);
  EXPECT_EQ(c.seq, 10u);
  EXPECT_FALSE(v.readIfNewer(c, seen));
  v.write(makeChecked(11));
  v.write(makeChecked(12));
  ASSERT_TRUE(v.readIfNewer(c, seen));
  EXPECT_EQ(seen, 3u);
  EXPECT_EQ(c.seq, 12u);
}

TEST(LatestValue, CarriesNavigationStateAndServiceStatus) {
  LatestValue<NavigationState> nav;
  nav.write(makeNav(42));
  const NavigationState n = nav.read();
  EXPECT_EQ(n.t_ns, 42);
  EXPECT_TRUE(matchesNav(n));

  LatestValue<ServiceStatus> status;
  ServiceStatus s;
  s.state = TrackingState::kDegraded;
  s.queue_overflows = 3;
  s.max_update_ms = 12.5;
  s.last_fault = {'s', 'p', 'i', '\0'};
  status.write(s);
  const ServiceStatus r = status.read();
  EXPECT_EQ(r.state, TrackingState::kDegraded);
  EXPECT_EQ(r.queue_overflows, 3u);
  EXPECT_EQ(r.max_update_ms, 12.5);
  EXPECT_STREQ(r.last_fault.data(), "spi");
}

// One writer, several readers, values with an internal checksum: no reader
// ever accepts a torn copy, versions never go backwards, and the version
// reported is the number of the write the value came from.
TEST(LatestValueStress, ReadersNeverSeeTornValues) {
  constexpr std::uint64_t kWrites = 200'000;
  constexpr int kReaders = 3;
  LatestValue<Checked> v(makeChecked(0));
  std::atomic<bool> done{false};
  std::vector<std::uint64_t> torn(kReaders, 0), backwards(kReaders, 0), mismatched(kReaders, 0), reads(kReaders, 0);
  std::vector<std::thread> readers;
  for (int r = 0; r < kReaders; ++r) {
    readers.emplace_back([&, r] {
      std::uint64_t last = 0;
      while (!done.load(std::memory_order_acquire)) {
        Checked c;
        std::uint64_t version = 0;
        if (!v.tryRead(c, &version)) continue;
        ++reads[static_cast<std::size_t>(r)];
        if (!intact(c)) ++torn[static_cast<std::size_t>(r)];
        if (version < last) ++backwards[static_cast<std::size_t>(r)];
        if (c.seq != version) ++mismatched[static_cast<std::size_t>(r)];
        last = version;
      }
    });
  }
  for (std::uint64_t k = 1; k <= kWrites; ++k) v.write(makeChecked(k));
  done.store(true, std::memory_order_release);
  for (auto& t : readers) t.join();
  for (int r = 0; r < kReaders; ++r) {
    const auto i = static_cast<std::size_t>(r);
    EXPECT_EQ(torn[i], 0u) << "reader " << r << " of " << reads[i] << " reads";
    EXPECT_EQ(backwards[i], 0u) << "reader " << r;
    EXPECT_EQ(mismatched[i], 0u) << "reader " << r;
  }
  std::uint64_t version = 0;
  const Checked last = v.read(&version);
  EXPECT_EQ(version, kWrites);
  EXPECT_EQ(last.seq, kWrites);
  EXPECT_TRUE(intact(last));
}

TEST(LatestValueStress, NavigationStateStaysConsistent) {
  constexpr std::int64_t kWrites = 50'000;
  LatestValue<NavigationState> v(makeNav(0));
  std::atomic<bool> done{false};
  std::uint64_t bad = 0, reads = 0;
  std::thread reader([&] {
    while (!done.load(std::memory_order_acquire)) {
      NavigationState s;
      if (!v.tryRead(s)) continue;
      ++reads;
      if (!matchesNav(s)) ++bad;
    }
  });
  for (std::int64_t k = 1; k <= kWrites; ++k) v.write(makeNav(k));
  done.store(true, std::memory_order_release);
  reader.join();
  EXPECT_EQ(bad, 0u) << "of " << reads << " reads";
  EXPECT_EQ(v.read().t_ns, kWrites);
}

}  // namespace
}  // namespace rilo
