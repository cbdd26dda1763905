#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "devices/dw3000_test_rig.h"
#include "hal/dw3000/dw3000_source.h"

namespace rilo::dw3000 {
namespace {

using testing::CollectingSink;
using testing::Rig;
using State = AnchorScheduler::State;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kS = 1'000'000'000;

/// Six anchors: four near (2-5 m), two far (20, 30 m), mixed clock offsets.
void addSixAnchors(Rig& rig) {
  rig.addAnchor(10, 0x0010, 2.0, 12.0);
  rig.addAnchor(11, 0x0011, 3.0, -8.0);
  rig.addAnchor(12, 0x0012, 4.0, 20.0);
  rig.addAnchor(13, 0x0013, 5.0, -20.0);
  rig.addAnchor(14, 0x0014, 20.0, 3.0);
  rig.addAnchor(15, 0x0015, 30.0, 0.0);
}

TEST(Dw3000Source, RangesTheStrongestFourAtTenHertzAndRediscoversTheOthers) {
  Rig rig;
  addSixAnchors(rig);
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  EXPECT_EQ(source.describe(), "dwm3000 emu:spidev0.0 (channel 5, 6 anchors, strongest 4 at 10 Hz)");
  CollectingSink sink;
  const std::int64_t start = rig.clock.nowNs();
  EXPECT_EQ(rig.run(source, sink, 3 * kS), SourceEnd::kStopped);
  EXPECT_TRUE(sink.faults.empty()) << sink.faults.front().what;

  for (std::uint32_t id = 10; id <= 13; ++id) {
    EXPECT_EQ(source.scheduler().state(id - 10), State::kActive) << id;
    // 10 Hz for 3 s (+1 from the sweep), never faster.
    EXPECT_GE(sink.rangesFrom(id), 29u) << id;
    EXPECT_LE(sink.rangesFrom(id), 32u) << id;
  }
  for (std::uint32_t id = 14; id <= 15; ++id) {
    EXPECT_EQ(source.scheduler().state(id - 10), State::kCandidate) << id;
    // One rediscovery poll per 250 ms shared by the two: ~6 each.
    EXPECT_GE(sink.rangesFrom(id), 4u) << id;
    EXPECT_LE(sink.rangesFrom(id), 8u) << id;
  }
  // Samples: increasing time, the right tag, accurate ranges.
  std::int64_t last = start;
  const double truth[] = {2.0, 3.0, 4.0, 5.0, 20.0, 30.0};
  for (const RangeSample& r : sink.ranges) {
    EXPECT_GE(r.t_ns, last);
    last = r.t_ns;
    EXPECT_EQ(r.tag_id, 0u);
    EXPECT_NEAR(r.range_m, truth[r.anchor_id - 10], 0.01);
    // RX level and first-path power of the emulated channel (default model:
    // -63 dBm at 1 m, 2 dB below it in the first path); C is a few counts at
    // 30 m, so its rounding allows ~0.4 dB there.
    const double rx_level_dbm = -63.0 - 20.0 * std::log10(truth[r.anchor_id - 10]);
    EXPECT_NEAR(r.rssi_dbm, rx_level_dbm, 0.5);
    EXPECT_NEAR(r.fp_power_dbm, rx_level_dbm - 2.0, 0.01);
    EXPECT_EQ(r.los, -1);  // ground truth only simulators know
  }
  const auto& stats = source.stats();
  EXPECT_EQ(Dw3000Stats::get(stats.ranges), sink.ranges.size());
  EXPECT_EQ(Dw3000Stats::get(stats.exchanges), sink.ranges.size());
  EXPECT_EQ(Dw3000Stats::get(stats.diagnostics_read_failures), 0u);
  EXPECT_EQ(Dw3000Stats::get(stats.bringups), 1u);
  EXPECT_GE(Dw3000Stats::get(stats.discovery_polls), 6u + 10u);
  EXPECT_EQ(rig.chip.counters().speed_violations, 0u);
}

TEST(Dw3000Source, AnAnchorThatComesCloseIsSwappedIn) {
  Rig rig;
  addSixAnchors(rig);
  const std::int64_t t_move = rig.clock.nowNs() + 1 * kS;
  // Anchor 15 jumps from 30 m to 1 m (the tag walked past it).
  rig.chip.responder(5).distance_m = [t_move](std::int64_t t) { return t < t_move ? 30.0 : 1.0; };
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  CollectingSink sink;
  rig.run(source, sink, 3 * kS);
  EXPECT_EQ(source.scheduler().state(5), State::kActive);
  EXPECT_EQ(source.scheduler().state(3), State::kCandidate);  // the weakest (5 m) made room
  // Swapped in at its first rediscovery poll after the move (two candidates
  // x 250 ms), then ranged at 10 Hz for the remaining 1.4 s; the dropped one
  // is only rediscovered (every 500 ms).
  EXPECT_GE(sink.rangesFrom(15, t_move + 600 * kMs), 13u);
  EXPECT_LE(sink.rangesFrom(15, t_move + 600 * kMs), 15u);
  EXPECT_LE(sink.rangesFrom(13, t_move + 600 * kMs), 4u);
}

TEST(Dw3000Source, AnAnchorThatDisappearsIsDroppedAfterBackedOffRetries) {
  Rig rig;
  addSixAnchors(rig);
  const std::int64_t t_gone = rig.clock.nowNs() + 1 * kS;
  rig.clock.schedule(t_gone, [&rig] { rig.chip.responder(1).present = false; });  // anchor 11
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  CollectingSink sink;
  rig.run(source, sink, 3 * kS);
  // Two reported retries then the drop, each naming the anchor.
  EXPECT_EQ(sink.faultsContaining("RX timeout from anchor 11 (0x0011)"), 3u);
  EXPECT_EQ(sink.faultsContaining("retry in 20 ms"), 1u);
  EXPECT_EQ(sink.faultsContaining("retry in 40 ms"), 1u);
  EXPECT_EQ(sink.faultsContaining("dropped from the ranging set after 3 failures"), 1u);
  for (const SourceFault& f : sink.faults) {
    EXPECT_FALSE(f.fatal);
    EXPECT_EQ(f.device, "emu:spidev0.0");
  }
  // Back-off: the three attempts are 20 then 40 ms apart.
  ASSERT_GE(sink.faults.size(), 3u);
  EXPECT_GE(sink.faults[1].t_ns - sink.faults[0].t_ns, 20 * kMs);
  EXPECT_GE(sink.faults[2].t_ns - sink.faults[1].t_ns, 40 * kMs);
  EXPECT_EQ(source.scheduler().state(1), State::kCandidate);
  EXPECT_EQ(source.scheduler().activeCount(), 4u);  // a far anchor took the place
  EXPECT_EQ(Dw3000Stats::get(source.stats().anchors_dropped), 1u);
  EXPECT_EQ(sink.rangesFrom(11, t_gone), 0u);
  EXPECT_GE(sink.rangesFrom(14, t_gone + 500 * kMs), 10u);
  // Absent-anchor rediscovery polls are counted, not reported.
  EXPECT_GT(Dw3000Stats::get(source.stats().rx_timeouts), 3u);
}

TEST(Dw3000Source, StopsWhenAsked) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  CollectingSink sink;
  const std::int64_t start = rig.clock.nowNs();
  EXPECT_EQ(rig.run(source, sink, 200 * kMs), SourceEnd::kStopped);
  EXPECT_GE(sink.ranges.size(), 2u);
  // Sleeps are cut into chunks so the stop flag is seen promptly.
  EXPECT_LE(rig.clock.nowNs() - start, 250 * kMs);
}

}  // namespace
}  // namespace rilo::dw3000
