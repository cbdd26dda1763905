// FaultInjectingSource: each kind of fault does exactly what fault_injection.h
// says, at the sample time it says, to the stream it says, and nothing else.
#include "rilod/fault_injection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <stdexcept>
#include <variant>
#include <vector>

#include "service/support/vector_source.h"

namespace rilo {
namespace {

constexpr std::int64_t kT0 = 5'000'000'000;     // first sample time (not 0: at_s is relative)
constexpr std::int64_t kImuPeriod = 10'000'000;  // 100 Hz
constexpr std::int64_t kRangePeriod = 50'000'000;

std::int64_t timeOf(const Sample& s) {
  return std::visit([](const auto& v) { return v.t_ns; }, s);
}
bool isImu(const Sample& s) { return std::holds_alternative<ImuSample>(s); }

/// IMU at 100 Hz and a range every 50 ms (anchor = index), merged in time
/// order like a replay (IMU first at equal times), for `seconds`.
std::vector<Sample> stream(double seconds) {
  std::vector<Sample> out;
  const auto end = kT0 + static_cast<std::int64_t>(seconds * 1e9);
  std::uint32_t anchor = 0;
  for (std::int64_t t = kT0; t < end; t += kImuPeriod) {
    ImuSample imu;
    imu.t_ns = t;
    imu.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.81);
    out.emplace_back(imu);
    if ((t - kT0) % kRangePeriod == 0) {
      RangeSample r;
      r.t_ns = t;
      r.anchor_id = anchor++ % 4;
      r.range_m = 3.0;
      out.emplace_back(r);
    }
  }
  return out;
}

using testing::VectorSource;

class CollectingSink final : public SampleSink {
 public:
  void push(const Sample& s) noexcept override { samples.push_back(s); }
  void fault(const SourceFault& f) noexcept override { faults.push_back(f); }
  void note(const SourceNote& n) noexcept override { notes.push_back(n); }
  std::vector<Sample> samples;
  std::vector<SourceFault> faults;
  std::vector<SourceNote> notes;
};

struct Injected {
  std::vector<Sample> out;
  InjectedFaults injected;
  SourceEnd end = SourceEnd::kStopped;
};

Injected inject(const std::vector<Sample>& input, std::vector<FaultSpec> faults) {
  FaultInjectingSource source(std::make_unique<VectorSource>(input), std::move(faults));
  CollectingSink sink;
  std::atomic<bool> stop{false};
  Injected r;
  r.end = source.run(sink, stop);
  r.out = std::move(sink.samples);
  r.injected = source.injected();
  return r;
}

FaultSpec window(FaultKind kind, double at_s, double duration_s) {
  FaultSpec f;
  f.kind = kind;
  f.at_s = at_s;
  f.duration_s = duration_s;
  return f;
}

FaultSpec counted(FaultKind kind, double at_s, std::uint32_t count, FaultStream stream = FaultStream::kAll) {
  FaultSpec f;
  f.kind = kind;
  f.at_s = at_s;
  f.count = count;
  f.stream = stream;
  return f;
}

bool sameSample(const Sample& a, const Sample& b) {
  if (a.index() != b.index() || timeOf(a) != timeOf(b)) return false;
  if (const auto* r = std::get_if<RangeSample>(&a)) return r->anchor_id == std::get<RangeSample>(b).anchor_id;
  return true;
}

TEST(FaultInjection, WithoutFaultsTheStreamPassesUnchanged) {
  const auto input = stream(1.0);
  const Injected r = inject(input, {});
  EXPECT_EQ(r.end, SourceEnd::kEndOfData);
  ASSERT_EQ(r.out.size(), input.size());
  for (std::size_t i = 0; i < input.size(); ++i) EXPECT_TRUE(sameSample(r.out[i], input[i])) << i;
  EXPECT_EQ(r.injected.dropped + r.injected.corrupted + r.injected.reordered + r.injected.duplicated, 0u);
}

TEST(FaultInjection, RangeBlackoutDropsEveryRangeInItsWindowOnly) {
  const auto input = stream(3.0);
  const Injected r = inject(input, {window(FaultKind::kRangeBlackout, 1.0, 1.0)});
  std::size_t imu = 0, ranges_in = 0, ranges_out = 0;
  for (const Sample& s : input) (isImu(s) ? imu : ranges_in) += 1;
  for (const Sample& s : r.out) {
    if (isImu(s)) continue;
    ++ranges_out;
    const std::int64_t rel = timeOf(s) - kT0;
    EXPECT_TRUE(rel < 1'000'000'000 || rel >= 2'000'000'000) << "range at " << rel;
  }
  EXPECT_EQ(ranges_in - ranges_out, 20u);  // 1 s of ranges at 20 Hz
  EXPECT_EQ(r.out.size(), imu + ranges_out);  // every IMU sample kept
  EXPECT_EQ(r.injected.dropped, 20u);
}

TEST(FaultInjection, ImuGapDropsEveryImuSampleInItsWindowOnly) {
  const auto input = stream(2.0);
  const Injected r = inject(input, {window(FaultKind::kImuGap, 0.5, 0.25)});
  std::int64_t previous = -1, longest = 0;
  std::size_t ranges = 0;
  for (const Sample& s : r.out) {
    if (!isImu(s)) {
      ++ranges;
      continue;
    }
    if (previous >= 0) longest = std::max(longest, timeOf(s) - previous);
    previous = timeOf(s);
  }
  EXPECT_EQ(longest, 260'000'000);  // 25 samples gone: 0.49 s -> 0.75 s
  EXPECT_EQ(ranges, 40u);          // ranges untouched
  EXPECT_EQ(r.injected.dropped, 25u);
}

TEST(FaultInjection, DuplicateDeliversTheNextSamplesTwice) {
  const auto input = stream(1.0);
  const Injected r = inject(input, {counted(FaultKind::kDuplicate, 0.5, 3, FaultStream::kImu)});
  ASSERT_EQ(r.out.size(), input.size() + 3);
  EXPECT_EQ(r.injected.duplicated, 3u);
  std::size_t repeats = 0;
  for (std::size_t i = 1; i < r.out.size(); ++i) {
    if (isImu(r.out[i]) && sameSample(r.out[i], r.out[i - 1])) {
      ++repeats;
      EXPECT_GE(timeOf(r.out[i]) - kT0, 500'000'000);
    }
  }
  EXPECT_EQ(repeats, 3u);
}

TEST(FaultInjection, OutOfOrderDeliversASampleAfterItsSuccessorOfTheSameKind) {
  const auto input = stream(1.0);
  const Injected r = inject(input, {counted(FaultKind::kOutOfOrder, 0.3, 2, FaultStream::kRanging)});
  ASSERT_EQ(r.out.size(), input.size());  // nothing lost, nothing added
  EXPECT_EQ(r.injected.reordered, 2u);
  std::int64_t last_range = -1;
  std::size_t backwards = 0;
  for (const Sample& s : r.out) {
    if (isImu(s)) continue;
    if (timeOf(s) < last_range) {
      ++backwards;
      EXPECT_EQ(last_range - timeOf(s), kRangePeriod);  // one range late
    }
    last_range = std::max(last_range, timeOf(s));
  }
  EXPECT_EQ(backwards, 2u);
  // IMU order untouched.
  std::int64_t last_imu = -1;
  for (const Sample& s : r.out) {
    if (!isImu(s)) continue;
    EXPECT_GT(timeOf(s), last_imu);
    last_imu = timeOf(s);
  }
}

TEST(FaultInjection, OutOfOrderOnAllStreamsAffectsEachKindSeparately) {
  const auto input = stream(1.0);
  const Injected r = inject(input, {counted(FaultKind::kOutOfOrder, 0.0, 4)});
  ASSERT_EQ(r.out.size(), input.size());
  EXPECT_EQ(r.injected.reordered, 4u);
  std::int64_t last[2] = {-1, -1};
  std::size_t backwards[2] = {0, 0};
  for (const Sample& s : r.out) {
    const int k = isImu(s) ? 0 : 1;
    if (timeOf(s) < last[k]) ++backwards[k];
    last[k] = std::max(last[k], timeOf(s));
  }
  EXPECT_EQ(backwards[0] + backwards[1], 4u);
  EXPECT_GT(backwards[0], 0u);
  EXPECT_GT(backwards[1], 0u);
}

TEST(FaultInjection, AHeldSampleIsDeliveredAtTheEndOfTheData) {
  std::vector<Sample> input = stream(0.1);
  const Injected r = inject(input, {counted(FaultKind::kOutOfOrder, 0.09, 1, FaultStream::kImu)});
  ASSERT_EQ(r.out.size(), input.size());
  EXPECT_TRUE(sameSample(r.out.back(), input.back()));
}

TEST(FaultInjection, ImpossibleGivesValuesNoSensorGives) {
  const auto input = stream(1.0);
  const Injected r = inject(input, {counted(FaultKind::kImpossible, 0.2, 2, FaultStream::kImu),
                               counted(FaultKind::kImpossible, 0.2, 2, FaultStream::kRanging)});
  ASSERT_EQ(r.out.size(), input.size());
  EXPECT_EQ(r.injected.impossible, 4u);
  EXPECT_EQ(r.injected.corrupted, 0u);
  std::size_t huge_accel = 0;
  std::vector<double> bad_ranges;
  for (const Sample& s : r.out) {
    if (const auto* imu = std::get_if<ImuSample>(&s)) {
      if (imu->accel_m_s2.x() == 1e30) {
        ++huge_accel;
        EXPECT_GE(imu->t_ns - kT0, 200'000'000);
      }
    } else if (const auto* range = std::get_if<RangeSample>(&s)) {
      if (range->range_m != 3.0) bad_ranges.push_back(range->range_m);
    }
  }
  EXPECT_EQ(huge_accel, 2u);
  ASSERT_EQ(bad_ranges.size(), 2u);
  EXPECT_EQ(bad_ranges[0] * bad_ranges[1], -5.0 * 1e9);  // one of each, in either order
}

TEST(FaultInjection, NonFiniteAlternatesNanAndInfinityInTheValue) {
  const auto input = stream(1.0);
  // In stream order: IMU 0.20 (NaN), range 0.20 (inf), IMU 0.21 (NaN), IMU 0.22 (inf).
  const Injected r = inject(input, {counted(FaultKind::kNonFinite, 0.2, 3, FaultStream::kImu),
                               counted(FaultKind::kNonFinite, 0.2, 1, FaultStream::kRanging)});
  ASSERT_EQ(r.out.size(), input.size());
  EXPECT_EQ(r.injected.corrupted, 4u);
  std::size_t nan = 0, inf = 0, bad_ranges = 0;
  for (const Sample& s : r.out) {
    if (const auto* imu = std::get_if<ImuSample>(&s)) {
      EXPECT_TRUE(imu->gyro_rad_s.allFinite());
      if (std::isnan(imu->accel_m_s2.x())) ++nan;
      if (std::isinf(imu->accel_m_s2.x())) ++inf;
      if (!imu->accel_m_s2.allFinite()) {
        EXPECT_GE(imu->t_ns - kT0, 200'000'000);
      }
    } else if (const auto* range = std::get_if<RangeSample>(&s)) {
      if (!std::isfinite(range->range_m)) ++bad_ranges;
    }
  }
  EXPECT_EQ(bad_ranges, 1u);
  EXPECT_EQ(nan, 2u);
  EXPECT_EQ(inf, 1u);
}

TEST(FaultInjection, TimesAreRelativeToTheFirstSampleWhateverItsClock) {
  auto input = stream(2.0);
  for (Sample& s : input) std::visit([](auto& v) { v.t_ns += 1'000'000'000'000; }, s);  // shifted clock
  const Injected r = inject(input, {window(FaultKind::kImuGap, 1.0, 0.1)});
  EXPECT_EQ(r.injected.dropped, 10u);
}

TEST(FaultInjection, StopPassesThroughAndFaultsAndNotesAreForwarded) {
  class FaultySource final : public SampleSource {
   public:
    SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override {
      sink.note(SourceNote{0, "dev", "started: trims from OTP"});
      sink.fault(SourceFault{1, "dev", "broken", false});
      return stop.load() ? SourceEnd::kStopped : SourceEnd::kEndOfData;
    }
    std::string describe() const override { return "faulty"; }
  };
  FaultInjectingSource source(std::make_unique<FaultySource>(), {});
  CollectingSink sink;
  std::atomic<bool> stop{true};
  EXPECT_EQ(source.run(sink, stop), SourceEnd::kStopped);
  ASSERT_EQ(sink.faults.size(), 1u);
  EXPECT_EQ(sink.faults[0].what, "broken");
  ASSERT_EQ(sink.notes.size(), 1u);
  EXPECT_EQ(sink.notes[0].what, "started: trims from OTP");
}

TEST(FaultInjection, DescribeListsTheFaults) {
  FaultInjectingSource source(std::make_unique<VectorSource>(std::vector<Sample>{}),
                              {window(FaultKind::kRangeBlackout, 20.0, 30.0),
                               counted(FaultKind::kDuplicate, 12.0, 5, FaultStream::kImu),
                               counted(FaultKind::kNonFinite, 1.5, 1)});
  EXPECT_EQ(source.describe(),
            "vector with injected faults: range_blackout 30 s at 20 s, duplicate 5 imu samples at 12 s, "
            "non_finite 1 sample at 1.5 s");
}

TEST(FaultInjection, InvalidFaultsAreRejectedNamingTheField) {
  auto message = [](const FaultSpec& f) -> std::string {
    try {
      FaultInjectingSource source(std::make_unique<VectorSource>(std::vector<Sample>{}), {f});
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "accepted";
  };
  EXPECT_NE(message(window(FaultKind::kImuGap, -1.0, 1.0)).find("FaultSpec.at_s"), std::string::npos);
  EXPECT_NE(message(window(FaultKind::kImuGap, 1.0, 0.0)).find("FaultSpec.duration_s"), std::string::npos);
  EXPECT_NE(message(counted(FaultKind::kDuplicate, 1.0, 0)).find("FaultSpec.count"), std::string::npos);
  EXPECT_THROW(FaultInjectingSource(nullptr, {}), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
