// Office simulator, second system (IMU-Ultrasonic-UWB paper): UWB TDoA (differences match the
// geometry, NLOS bias has the sign of the blocked anchor, packet reception at
// the option's rate, the TDMA schedule) and ultrasonic ranging (beacons on
// the ceiling, never through a wall nor beyond max range, centimetre noise,
// reflections longer, the speed-of-sound scale, the ping schedule).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>
#include <vector>

#include "sim/office.h"
#include "sim/office_scenario.h"
#include "sim/office_tdoa.h"
#include "sim/office_ultrasonic.h"

namespace rilo::sim {
namespace {

OfficeScenarioParams tdoaParams(std::uint64_t seed, double duration_s) {
  OfficeScenarioParams p;
  p.seed = seed;
  p.duration_s = duration_s;
  p.tdoa.enabled = true;
  return p;
}

OfficeScenarioParams ultrasonicParams(std::uint64_t seed, double duration_s) {
  OfficeScenarioParams p;
  p.seed = seed;
  p.duration_s = duration_s;
  p.ultrasonic.enabled = true;
  return p;
}

struct TdoaRun {
  OfficeSetup setup;
  std::vector<TdoaSample> samples;
  std::vector<TdoaTruth> truth;
  TdoaStats stats;
};

TdoaRun runTdoa(const OfficeScenarioParams& p) {
  TdoaRun run;
  run.setup = makeOfficeSetup(p);
  OfficeTdoaStream stream(p, run.setup);
  TdoaSample s;
  TdoaTruth t;
  while (stream.next(s, t)) {
    run.samples.push_back(s);
    run.truth.push_back(t);
  }
  run.stats = stream.stats();
  EXPECT_EQ(stream.progress(), 1.0);
  return run;
}

struct UltrasonicRun {
  OfficeSetup setup;
  std::vector<UltrasonicSample> samples;
  std::vector<UltrasonicTruth> truth;
  UltrasonicStats stats;
};

UltrasonicRun runUltrasonic(const OfficeScenarioParams& p) {
  UltrasonicRun run;
  run.setup = makeOfficeSetup(p);
  OfficeUltrasonicStream stream(p, run.setup);
  UltrasonicSample s;
  UltrasonicTruth t;
  while (stream.next(s, t)) {
    run.samples.push_back(s);
    run.truth.push_back(t);
  }
  run.stats = stream.stats();
  return run;
}

double secondsOf(const OfficeScenarioParams& p, std::int64_t t_ns) { return 1e-9 * static_cast<double>(t_ns - p.t0_ns); }

// ---- TDoA ---------------------------------------------------------------------

TEST(OfficeTdoa, DifferencesMatchTheGeometryAndLosRowsAreWithinTheNoise) {
  const OfficeScenarioParams p = tdoaParams(2, 300.0);
  const TdoaRun run = runTdoa(p);
  ASSERT_GT(run.samples.size(), 20000u);
  const std::size_t n_anchors = run.setup.p_w_anchors.size();
  double sum = 0.0, sum_sq = 0.0;
  int n_los = 0;
  for (std::size_t i = 0; i < run.samples.size(); ++i) {
    const TdoaSample& s = run.samples[i];
    const TdoaTruth& t = run.truth[i];
    ASSERT_LT(s.anchor_a, n_anchors);
    ASSERT_LT(s.anchor_b, n_anchors);
    ASSERT_NE(s.anchor_a, s.anchor_b);
    if (i > 0) {
      ASSERT_GT(s.t_ns, run.samples[i - 1].t_ns);
    }
    // The truth is the geometry of the tag antenna at t.
    const Vec3 p_tag = run.setup.walk->at(secondsOf(p, s.t_ns)).T_w_b.transformFrom(p.p_b_tag);
    const double geometry = (p_tag - run.setup.p_w_anchors[s.anchor_b]).norm() -
                            (p_tag - run.setup.p_w_anchors[s.anchor_a]).norm();
    ASSERT_NEAR(t.true_diff_m, geometry, 1e-6) << i;
    ASSERT_NEAR(s.diff_m - t.true_diff_m, t.error_m, 1e-12);
    ASSERT_EQ(s.los, t.los_a && t.los_b ? 1 : 0);
    if (t.outlier) continue;
    // error = excess_b - excess_a + bias + noise (noise below 6 sigma, sigma 0.15 m or 1.5x under NLOS).
    const double noise = t.error_m - (t.excess_b_m - t.excess_a_m) - t.bias_m;
    ASSERT_LT(std::abs(noise), 6.0 * 0.15 * (s.los == 1 ? 1.0 : 1.5)) << i;
    ASSERT_LT(std::abs(t.bias_m), 6.0 * std::sqrt(2.0) * 0.02);
    if (s.los == 1) {
      ASSERT_EQ(t.excess_a_m, 0.0);
      ASSERT_EQ(t.excess_b_m, 0.0);
      ASSERT_LT(std::abs(s.diff_m - geometry), 6.0 * 0.15 + 0.2) << i;
      sum += t.error_m - t.bias_m;
      sum_sq += (t.error_m - t.bias_m) * (t.error_m - t.bias_m);
      ++n_los;
    }
  }
  ASSERT_GT(n_los, 200);
  const double mean = sum / n_los;
  EXPECT_LT(std::abs(mean), 0.03);
  EXPECT_NEAR(std::sqrt(sum_sq / n_los - mean * mean), 0.15, 0.02);
  EXPECT_EQ(run.stats.measurements, run.samples.size());
  EXPECT_EQ(run.stats.nlos, static_cast<std::size_t>(std::count_if(
                                run.samples.begin(), run.samples.end(), [](const TdoaSample& s) { return s.los == 0; })));
}

TEST(OfficeTdoa, NlosBiasHasTheSignOfTheBlockedAnchor) {
  const TdoaRun run = runTdoa(tdoaParams(3, 300.0));
  double b_sum = 0.0, a_sum = 0.0;
  int b_rows = 0, a_rows = 0, b_positive = 0, a_negative = 0;
  for (std::size_t i = 0; i < run.samples.size(); ++i) {
    const TdoaTruth& t = run.truth[i];
    if (t.outlier || t.los_a == t.los_b) continue;
    EXPECT_EQ(run.samples[i].los, 0);
    if (!t.los_b) {  // only anchor_b's path blocked: the difference is too long
      EXPECT_GT(t.excess_b_m, 0.0);
      EXPECT_EQ(t.excess_a_m, 0.0);
      b_sum += t.error_m;
      b_positive += t.error_m > 0.0 ? 1 : 0;
      ++b_rows;
    } else {  // only the reference path blocked: too short
      EXPECT_GT(t.excess_a_m, 0.0);
      EXPECT_EQ(t.excess_b_m, 0.0);
      a_sum += t.error_m;
      a_negative += t.error_m < 0.0 ? 1 : 0;
      ++a_rows;
    }
  }
  ASSERT_GT(b_rows, 1000);
  ASSERT_GT(a_rows, 1000);
  EXPECT_GT(b_sum / b_rows, 0.2);
  EXPECT_LT(a_sum / a_rows, -0.2);
  EXPECT_GT(static_cast<double>(b_positive) / b_rows, 0.75);
  EXPECT_GT(static_cast<double>(a_negative) / a_rows, 0.75);
  EXPECT_LE(run.stats.nlos_b_only + run.stats.nlos_a_only, run.stats.nlos);
  EXPECT_GT(run.stats.meanNlosPathExcess(), 0.1);
}

TEST(OfficeTdoa, EveryRowCarriesBothPacketsDiagnosticsAndTheGapFlagsNlosPaths) {
  const TdoaRun run = runTdoa(tdoaParams(3, 120.0));
  ASSERT_GT(run.samples.size(), 5000u);
  const double sensitivity_dbm = run.setup.channel->params().sensitivity_dbm;
  int los_paths = 0, los_flagged = 0, nlos_paths = 0, nlos_flagged = 0;
  for (std::size_t i = 0; i < run.samples.size(); ++i) {
    const TdoaSample& s = run.samples[i];
    const TdoaTruth& t = run.truth[i];
    for (const auto& [rssi, fp, los] : {std::tuple{s.rssi_a_dbm, s.fp_power_a_dbm, t.los_a},
                                        std::tuple{s.rssi_b_dbm, s.fp_power_b_dbm, t.los_b}}) {
      ASSERT_TRUE(std::isfinite(rssi) && std::isfinite(fp)) << "row " << i;
      EXPECT_GT(rssi, sensitivity_dbm - 30.0);  // heard: mean level plus fading reached the sensitivity
      const double gap_db = rssi - fp;
      EXPECT_GE(gap_db, 1.5);
      const bool flagged = gap_db > 6.0;  // RangeNoiseParams::nlos_power_gap_db
      (los ? los_paths : nlos_paths) += 1;
      (los ? los_flagged : nlos_flagged) += flagged ? 1 : 0;
    }
  }
  // The reference's diagnostics are those of its own packet, a round earlier,
  // so a path that just changed state is rare but possible on either side.
  ASSERT_GT(los_paths, 1000);
  ASSERT_GT(nlos_paths, 1000);
  EXPECT_LT(static_cast<double>(los_flagged) / los_paths, 0.05);
  EXPECT_GT(static_cast<double>(nlos_flagged) / nlos_paths, 0.6);
}

TEST(OfficeTdoa, PacketReceptionMatchesTheOption) {
  for (const double reception : {0.4, 0.95, 1.0}) {
    OfficeScenarioParams p = tdoaParams(4, 300.0);
    p.tdoa.packet_reception = reception;
    const TdoaStats st = runTdoa(p).stats;
    ASSERT_GT(st.heard, 20000u);
    // Binomial: 4 standard deviations.
    const double tol = 4.0 * std::sqrt(reception * (1.0 - reception) / static_cast<double>(st.heard)) + 1e-12;
    EXPECT_NEAR(st.reception(), reception, tol) << reception;
    EXPECT_EQ(st.rounds, (st.packets + 7u) / 8u);  // the last round may be cut by the end of the session
    EXPECT_EQ(st.measurements + st.no_reference, st.received);
    EXPECT_LE(st.heard, st.packets);
    if (reception == 1.0) {
      EXPECT_EQ(st.received, st.heard);
    }
  }
  // The IMU-Ultrasonic-UWB paper's 40 %: fewer rows, and more received packets find no reference within a round.
  OfficeScenarioParams low = tdoaParams(4, 120.0), high = low;
  low.tdoa.packet_reception = 0.4;
  const TdoaStats st_low = runTdoa(low).stats, st_high = runTdoa(high).stats;
  EXPECT_LT(st_low.measurements, st_high.measurements / 2);
  EXPECT_GT(static_cast<double>(st_low.no_reference) / static_cast<double>(st_low.received),
            static_cast<double>(st_high.no_reference) / static_cast<double>(st_high.received));
}

TEST(OfficeTdoa, AnchorsTransmitInTurnAndPairWithARecentAudibleReference) {
  OfficeScenarioParams p = tdoaParams(5, 60.0);
  p.tdoa.round_rate_hz = 10.0;
  p.anchors.count = 6;
  const OfficeSetup setup = makeOfficeSetup(p);
  OfficeTdoaStream stream(p, setup);
  const double slot_s = 1.0 / (10.0 * 6.0);
  TdoaSample s;
  TdoaTruth t;
  std::size_t rows = 0;
  std::set<std::uint32_t> seen_b;
  while (stream.next(s, t)) {
    ++rows;
    const double k = secondsOf(p, s.t_ns) / slot_s;
    ASSERT_NEAR(k, std::round(k), 1e-6);
    EXPECT_EQ(static_cast<std::uint32_t>(std::llround(k)) % 6u, s.anchor_b);
    EXPECT_GT(t.reference_age_s, 0.0);
    EXPECT_LE(t.reference_age_s, 0.1 + 1e-9);  // one round at 10 Hz
    EXPECT_TRUE(stream.anchorsHearEachOther(s.anchor_a, s.anchor_b));
    seen_b.insert(s.anchor_b);
  }
  EXPECT_GT(rows, 1000u);
  EXPECT_EQ(seen_b.size(), 6u);
  EXPECT_EQ(stream.stats().rounds, 601u);  // t = 0 .. 60 s at 10 Hz
  // Anchor-to-anchor audibility follows the walls: a pair in the same space hears each other.
  EXPECT_TRUE(stream.anchorsHearEachOther(0, 0) == false);
  const Vec3 a(1.0, 1.0, 2.5), b(4.0, 1.0, 2.5);
  EXPECT_GT(anchorToAnchorRssiDbm(*setup.plan, p.channel, a, b), p.channel.sensitivity_dbm);
  EXPECT_GT(anchorToAnchorRssiDbm(*setup.plan, p.channel, a, b),
            anchorToAnchorRssiDbm(*setup.plan, p.channel, a, Vec3(4.0, 11.0, 2.5)) + 10.0);
}

TEST(OfficeTdoa, OutliersAtTheirRateOnEitherPath) {
  OfficeScenarioParams p = tdoaParams(6, 300.0);
  p.tdoa.outlier_probability = 0.03;
  p.tdoa.early_outlier_fraction = 0.0;
  const TdoaRun run = runTdoa(p);
  EXPECT_NEAR(run.stats.outlierRate(), 0.03, 0.006);
  int on_b = 0, on_a = 0;
  for (std::size_t i = 0; i < run.samples.size(); ++i) {
    const TdoaTruth& t = run.truth[i];
    if (!t.outlier) continue;
    const double rest = t.error_m - (t.excess_b_m - t.excess_a_m) - t.bias_m;  // outlier + noise
    if (t.outlier_on_b) {
      EXPECT_GT(rest, 1.0 - 6.0 * 0.225);
      ++on_b;
    } else {
      EXPECT_LT(rest, -1.0 + 6.0 * 0.225);
      ++on_a;
    }
  }
  EXPECT_GT(on_b, 50);
  EXPECT_GT(on_a, 50);
}

TEST(OfficeTdoa, DeterministicPerSeedAndIndependentOfOtherOptions) {
  OfficeScenarioParams p = tdoaParams(7, 20.0);
  const TdoaRun a = runTdoa(p);
  // Other sensors and the SS-TWR options do not change the TDoA rows.
  p.ultrasonic.enabled = true;
  p.packet_loss = 0.3;
  p.tdoa.keep_twr = true;
  const TdoaRun b = runTdoa(p);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    ASSERT_EQ(a.samples[i].t_ns, b.samples[i].t_ns);
    ASSERT_EQ(a.samples[i].anchor_a, b.samples[i].anchor_a);
    ASSERT_EQ(a.samples[i].anchor_b, b.samples[i].anchor_b);
    ASSERT_EQ(a.samples[i].diff_m, b.samples[i].diff_m);
  }
  p.seed = 8;
  const TdoaRun c = runTdoa(p);
  EXPECT_NE(a.samples[10].diff_m, c.samples[10].diff_m);
}

TEST(OfficeTdoa, InvalidParamsThrow) {
  const OfficeScenarioParams good = tdoaParams(1, 5.0);
  EXPECT_NO_THROW(validate(good));
  auto expectThrow = [&](auto change) {
    OfficeScenarioParams p = good;
    change(p.tdoa);
    EXPECT_THROW(validate(p), std::invalid_argument);
  };
  expectThrow([](TdoaParams& t) { t.packet_reception = 0.0; });
  expectThrow([](TdoaParams& t) { t.packet_reception = 1.2; });
  expectThrow([](TdoaParams& t) { t.round_rate_hz = 0.0; });
  expectThrow([](TdoaParams& t) { t.sigma_m = -0.1; });
  expectThrow([](TdoaParams& t) { t.nlos_noise_factor = 0.5; });
  expectThrow([](TdoaParams& t) { t.max_reference_age_s = -1.0; });
  try {
    OfficeScenarioParams p = good;
    p.tdoa.packet_reception = 2.0;
    validate(p);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("packet_reception"), std::string::npos);
  }
  OfficeScenarioParams one = good;
  one.anchors.count = 1;
  const OfficeSetup setup = makeOfficeSetup(one);
  EXPECT_THROW(OfficeTdoaStream(one, setup), std::invalid_argument);
}

// ---- Ultrasonic ---------------------------------------------------------------

TEST(OfficeUltrasonic, BeaconsHangFromTheCeilingOfDifferentSpaces) {
  const OfficePlan plan = defaultOfficePlan();
  const UltrasonicParams up;
  const std::vector<Vec3> beacons = placeUltrasonicBeacons(plan, up);
  ASSERT_EQ(beacons.size(), 4u);
  std::set<int> spaces;
  for (const Vec3& b : beacons) {
    EXPECT_DOUBLE_EQ(b.z(), plan.ceiling_m - up.mount_below_ceiling_m);
    const int s = plan.spaceAt(b.head<2>());
    ASSERT_GE(s, 0);
    EXPECT_TRUE(plan.spaces[static_cast<std::size_t>(s)].inFree(b.head<2>()));
    spaces.insert(s);
  }
  EXPECT_EQ(spaces.size(), 4u);
  EXPECT_TRUE(plan.spaces[static_cast<std::size_t>(plan.spaceAt(beacons[0].head<2>()))].corridor);
  EXPECT_EQ(placeUltrasonicBeacons(plan, up), beacons);  // deterministic
  UltrasonicParams many = up;
  many.beacons = 60;
  many.ping_rate_hz = 0.1;
  EXPECT_THROW(placeUltrasonicBeacons(plan, many), std::invalid_argument);
  // Anchor ids follow the UWB anchors.
  EXPECT_EQ(ultrasonicAnchorId(8, 0), 8u);
  EXPECT_EQ(ultrasonicAnchorId(8, 3), 11u);
  // The setup places them only when enabled.
  EXPECT_TRUE(makeOfficeSetup(tdoaParams(1, 5.0)).p_w_ultrasonic.empty());
  EXPECT_EQ(makeOfficeSetup(ultrasonicParams(1, 5.0)).p_w_ultrasonic, beacons);
}

TEST(OfficeUltrasonic, NeverThroughAWallNorBeyondMaxRange) {
  const OfficeScenarioParams p = ultrasonicParams(2, 300.0);
  const UltrasonicRun run = runUltrasonic(p);
  const std::vector<Vec3>& beacons = run.setup.p_w_ultrasonic;
  const std::size_t n_uwb = run.setup.p_w_anchors.size();
  ASSERT_GT(run.samples.size(), 500u);
  std::set<std::pair<std::size_t, std::size_t>> measured;  // (ping slot, beacon)
  const double slot_s = 1.0 / (p.ultrasonic.ping_rate_hz * 4.0);
  for (std::size_t i = 0; i < run.samples.size(); ++i) {
    const UltrasonicSample& s = run.samples[i];
    const UltrasonicTruth& t = run.truth[i];
    ASSERT_GE(s.anchor_id, n_uwb);
    const std::size_t j = s.anchor_id - n_uwb;
    ASSERT_LT(j, beacons.size());
    ASSERT_EQ(j, t.beacon);
    if (i > 0) {
      ASSERT_GE(s.t_ns, run.samples[i - 1].t_ns);
    }
    const Vec3 p_rx = run.setup.walk->at(secondsOf(p, s.t_ns)).T_w_b.transformFrom(p.ultrasonic.p_b_receiver);
    const double d = (p_rx - beacons[j]).norm();
    ASSERT_NEAR(d, t.true_range_m, 1e-6);
    ASSERT_LE(d, p.ultrasonic.max_range_m);
    ASSERT_LE(s.range_m, p.ultrasonic.max_range_m);
    ASSERT_EQ(obstruction(*run.setup.plan, p_rx, beacons[j]).walls(), 0) << i;
    // Heard within its own ping slot (sound at 343 m/s).
    const double dt = secondsOf(p, s.t_ns) - t.emit_time_s;
    ASSERT_GT(dt, 0.0);
    ASSERT_LT(dt, slot_s);
    measured.insert({static_cast<std::size_t>(std::llround(t.emit_time_s / slot_s)), j});
  }
  // Independently of the stream's bookkeeping: a ping whose every path of the
  // echo window crosses a wall or is out of range is never measured.
  std::size_t blocked = 0, far = 0;
  for (std::size_t k = 0; static_cast<double>(k) * slot_s <= p.duration_s; ++k) {
    const std::size_t j = k % beacons.size();
    bool walled = true, out = true;
    for (double dt : {0.0, 0.25 * slot_s, 0.5 * slot_s, 0.75 * slot_s, slot_s}) {
      const Vec3 p_rx =
          run.setup.walk->at(static_cast<double>(k) * slot_s + dt).T_w_b.transformFrom(p.ultrasonic.p_b_receiver);
      walled = walled && obstruction(*run.setup.plan, p_rx, beacons[j]).walls() > 0;
      out = out && (p_rx - beacons[j]).norm() > p.ultrasonic.max_range_m + 0.05;
    }
    if (walled) {
      ++blocked;
      EXPECT_EQ(measured.count({k, j}), 0u) << "ping " << k << " through a wall";
    }
    if (out) {
      ++far;
      EXPECT_EQ(measured.count({k, j}), 0u) << "ping " << k << " beyond max range";
    }
  }
  EXPECT_GT(blocked, 1000u);  // the limits do bite in an office
  EXPECT_GT(far, 500u);
  EXPECT_GT(run.stats.wall_blocked, 0u);
  EXPECT_GT(run.stats.out_of_range, 0u);
  EXPECT_EQ(run.stats.pings, run.stats.measurements + run.stats.out_of_range + run.stats.wall_blocked +
                                 run.stats.obstacle_dropped + run.stats.dropouts);
}

TEST(OfficeUltrasonic, LosRangesAreCentimetreAccurateAndReflectionsLonger) {
  OfficeScenarioParams p = ultrasonicParams(3, 300.0);
  p.ultrasonic.reflection_probability = 1.0;  // every obstructed ping comes back as a reflection
  const UltrasonicRun run = runUltrasonic(p);
  double sum = 0.0, sum_sq = 0.0, reflection_sum = 0.0;
  int n_los = 0, n_reflection = 0;
  for (std::size_t i = 0; i < run.samples.size(); ++i) {
    const UltrasonicSample& s = run.samples[i];
    const UltrasonicTruth& t = run.truth[i];
    if (s.los == 1) {
      ASSERT_EQ(t.excess_m, 0.0);
      ASSERT_LT(std::abs(t.error_m), 6.0 * 0.02);
      sum += t.error_m;
      sum_sq += t.error_m * t.error_m;
      ++n_los;
    } else {
      ASSERT_GE(t.excess_m, p.ultrasonic.reflection_min_m);
      ASSERT_LE(t.excess_m, p.ultrasonic.reflection_max_m);
      ASSERT_NEAR(t.error_m, t.excess_m, 6.0 * 0.02);
      reflection_sum += t.error_m;
      ++n_reflection;
    }
  }
  ASSERT_GT(n_los, 500);
  ASSERT_GT(n_reflection, 30);
  const double mean = sum / n_los;
  EXPECT_LT(std::abs(mean), 0.005);
  EXPECT_NEAR(std::sqrt(sum_sq / n_los - mean * mean), 0.02, 0.004);
  EXPECT_GT(reflection_sum / n_reflection, p.ultrasonic.reflection_min_m);
  EXPECT_EQ(run.stats.reflections, static_cast<std::size_t>(n_reflection));
  EXPECT_EQ(run.stats.obstacle_dropped, 0u);
  // Without reflections, obstructed pings give no range at all.
  p.ultrasonic.reflection_probability = 0.0;
  const UltrasonicRun none = runUltrasonic(p);
  for (const UltrasonicSample& s : none.samples) ASSERT_EQ(s.los, 1);
  EXPECT_GT(none.stats.obstacle_dropped, 0u);
}

TEST(OfficeUltrasonic, SpeedOfSoundErrorScalesTheRangesAndTheArrivalTime) {
  OfficeScenarioParams p = ultrasonicParams(4, 60.0);
  p.ultrasonic.sigma_m = 0.0;
  p.ultrasonic.speed_of_sound_scale_error = 0.01;  // air ~5.5 C colder than assumed
  const UltrasonicRun run = runUltrasonic(p);
  int n = 0;
  for (std::size_t i = 0; i < run.samples.size(); ++i) {
    const UltrasonicTruth& t = run.truth[i];
    if (run.samples[i].los != 1) continue;
    ASSERT_NEAR(run.samples[i].range_m, 1.01 * t.true_range_m, 1e-9);
    // Sound flew t_ns - emit at c = 343 / 1.01 m/s (the receiver moved meanwhile: the path is the one at arrival).
    const double flight_s = secondsOf(p, run.samples[i].t_ns) - t.emit_time_s;
    ASSERT_NEAR(flight_s * 343.0 / 1.01, t.true_range_m, 1e-4);
    ++n;
  }
  EXPECT_GT(n, 100);
}

TEST(OfficeUltrasonic, PingScheduleMustLeaveTimeForTheEcho) {
  UltrasonicParams up;
  EXPECT_NO_THROW(validate(up));  // 4 beacons at 10 Hz: 25 ms per ping, 24 ms for 8 m
  up.beacons = 6;
  EXPECT_THROW(validate(up), std::invalid_argument);
  up.ping_rate_hz = 6.0;
  EXPECT_NO_THROW(validate(up));
  up = UltrasonicParams{};
  up.max_range_m = 10.0;
  try {
    validate(up);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ping_rate_hz"), std::string::npos) << e.what();
  }
  up = UltrasonicParams{};
  up.sigma_m = -0.01;
  EXPECT_THROW(validate(up), std::invalid_argument);
  up = UltrasonicParams{};
  up.speed_of_sound_scale_error = 0.5;
  EXPECT_THROW(validate(up), std::invalid_argument);
  up = UltrasonicParams{};
  up.reflection_max_m = 0.05;  // below reflection_min_m
  EXPECT_THROW(validate(up), std::invalid_argument);
}

TEST(OfficeUltrasonic, RatesAndDeterminism) {
  OfficeScenarioParams p = ultrasonicParams(5, 120.0);
  const UltrasonicRun a = runUltrasonic(p), b = runUltrasonic(p);
  EXPECT_EQ(a.stats.rounds, 1201u);  // t = 0 .. 120 s at 10 Hz
  EXPECT_EQ(a.stats.pings, 4u * 1200u + 1u);  // the last round is cut by the end of the session
  EXPECT_LE(a.stats.measurementsPerSecond(), 40.0);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    ASSERT_EQ(a.samples[i].t_ns, b.samples[i].t_ns);
    ASSERT_EQ(a.samples[i].range_m, b.samples[i].range_m);
  }
  p.ultrasonic.dropout = 0.5;
  const UltrasonicRun c = runUltrasonic(p);
  const double measurable = static_cast<double>(c.stats.measurements + c.stats.dropouts);
  EXPECT_NEAR(static_cast<double>(c.stats.dropouts) / measurable, 0.5, 4.0 * std::sqrt(0.25 / measurable));
}

}  // namespace
}  // namespace rilo::sim
