// `rilo probe`'s logic against the DW3000 and BMI263 emulators: bring-up
// facts, ranges to responders at known distances (within 1 cm, clock offsets
// corrected), the IMU stream at rest, and every failure naming its device.
#include "rilod/hardware_probe.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <system_error>

#include <nlohmann/json.hpp>

#include "evaluation/eval_test_support.h"
#include "rilod/config.h"
#include "service/emulated_board.h"
#include "service/service_test_support.h"

namespace rilo {
namespace {

using testing::BoardTruth;
using testing::EmulatedBoard;
using testing::TempDir;

constexpr double kGravity = 9.80665;

/// The JSON line of the anchor with this short address (one anchor per line).
/// The probe's entry of the anchor at `address` in uwb.anchors (null if none).
nlohmann::json anchorOf(const nlohmann::json& report, const std::string& address) {
  if (!report.contains("uwb") || !report["uwb"].contains("anchors")) return nullptr;
  for (const nlohmann::json& a : report["uwb"]["anchors"]) {
    if (a.value("short_address", "") == address) return a;
  }
  return nullptr;
}

class HardwareProbeTest : public ::testing::Test {
 protected:
  HardwareProbeTest() {
    testing::writeBlob(dir_ / "blob.bin");
    // Anchors 0..2 answer (clock offsets up to 20 ppm), anchor 3 is switched off.
    truth_.responders[0] = {2.5, 15.0};
    truth_.responders[1] = {4.0, -20.0};
    truth_.responders[2] = {7.25, 0.0};
  }

  ServiceConfig config(const std::string& extra = "") {
    return parseServiceConfig(testing::boardYaml(extra), dir_ / "rilod.yaml");
  }

  ProbeReport probe(const ServiceConfig& cfg, EmulatedBoard& board, double seconds = 3.0) {
    ProbeOptions options;
    options.seconds = seconds;
    return runProbe(cfg.sources.hardware, UwbProbeTarget{board.uwb(), ""}, ImuProbeTarget{board.imu(), ""}, options);
  }

  TempDir dir_{"probe"};
  BoardTruth truth_;
};

TEST_F(HardwareProbeTest, ReportsBringUpRangesAndTheImuAtRest) {
  const ServiceConfig cfg = config();
  EmulatedBoard board(cfg.sources.hardware, truth_);
  const ProbeReport report = probe(cfg, board);

  // DWM3000 bring-up.
  const UwbProbe& u = report.uwb;
  ASSERT_TRUE(u.up) << u.error;
  EXPECT_EQ(u.device, "emu:spidev0.0");
  EXPECT_EQ(u.dev_id, 0xDECA0302u);
  EXPECT_EQ(u.channel, 5);
  EXPECT_EQ(u.tx_antenna_delay, 16390);
  EXPECT_EQ(u.rx_antenna_delay, 16380);
  EXPECT_EQ(u.tx_antenna_delay_read, 16390);  // written to the chip
  EXPECT_EQ(u.rx_antenna_delay_read, 16380);
  EXPECT_NE(u.irq_mask, 0u);
  EXPECT_EQ(u.reinitializations, 0u);
  EXPECT_TRUE(u.device_faults.empty());
  EXPECT_NEAR(u.seconds, 3.0, 0.1);
  // The start-up: the chip's OTP trims applied, the PLL locked, the DGC
  // table loaded, the PGF calibrated.
  const emu::Dw3000Otp otp;
  EXPECT_TRUE(u.startup.ldo_bias_from_otp);
  EXPECT_EQ(u.startup.otp_ldo_tune_lo, otp.ldo_tune_lo);
  EXPECT_TRUE(u.startup.xtal_trim_from_otp);
  EXPECT_EQ(u.startup.xtal_trim, otp.xtal_trim);
  EXPECT_EQ(u.startup.otp_part_id, otp.part_id);
  EXPECT_GT(u.startup.pll_lock_ns, 0);
  EXPECT_TRUE(u.startup.dgc_on);
  EXPECT_TRUE(u.startup.pgf_done);
  // The first good frames' raw diagnostics, in the order ranged.
  ASSERT_EQ(u.first_frames.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    const FrameDiagnostics& f = u.first_frames[i];
    EXPECT_EQ(f.anchor_id, i);
    EXPECT_NEAR(f.range_m, truth_.responders[i].distance_m, 0.01);
    EXPECT_GT(f.raw.cir_power, 0u);
    EXPECT_GT(f.raw.fp_ampl1, 0u);
    EXPECT_EQ(f.raw.accumulation_count, emu::Dw3000EmulatorParams{}.preamble_accumulation_count);
    EXPECT_TRUE(std::isfinite(f.rssi_dbm));
  }

  // Ranges: each anchor polled at 10 Hz for 3 s, answering ones within 1 cm.
  ASSERT_EQ(u.anchors.size(), 4u);
  for (std::size_t i = 0; i < 3; ++i) {
    const AnchorProbe& a = u.anchors[i];
    SCOPED_TRACE(a.id);
    EXPECT_GE(a.attempts, 29u);
    EXPECT_LE(a.attempts, 31u);
    EXPECT_EQ(a.ranges(), a.attempts);
    EXPECT_DOUBLE_EQ(a.successRate(), 1.0);
    EXPECT_NEAR(a.range_m.mean, truth_.responders[a.id].distance_m, 0.01);
    EXPECT_NEAR(a.range_m.min, truth_.responders[a.id].distance_m, 0.01);
    EXPECT_NEAR(a.range_m.max, truth_.responders[a.id].distance_m, 0.01);
    EXPECT_LT(a.range_m.stddev(), 0.01);
    EXPECT_TRUE(a.errors.empty());
    // Positive when our clock (0 ppm) is slower than the responder's.
    EXPECT_NEAR(a.clock_offset_ppm.mean, truth_.responders[a.id].clock_ppm, 0.5);
    // RX level and first-path power from the emulated channel's diagnostics.
    const emu::Dw3000ResponderModel channel;  // the board's responders keep the defaults
    const double rx_level_dbm = channel.rx_level_at_1m_dbm - 20.0 * std::log10(truth_.responders[a.id].distance_m);
    EXPECT_EQ(a.rssi_dbm.count, a.ranges());
    EXPECT_EQ(a.fp_power_dbm.count, a.ranges());
    EXPECT_NEAR(a.rssi_dbm.mean, rx_level_dbm, 0.1);
    EXPECT_NEAR(a.rssi_dbm.mean - a.fp_power_dbm.mean, channel.nlos_gap_db(0), 0.1);
  }
  const AnchorProbe& off = u.anchors[3];
  EXPECT_GE(off.attempts, 29u);
  EXPECT_EQ(off.ranges(), 0u);
  EXPECT_DOUBLE_EQ(off.successRate(), 0.0);
  ASSERT_EQ(off.errors.count("RX timeout"), 1u);
  EXPECT_EQ(off.errors.at("RX timeout"), off.attempts);

  // BMI263 bring-up and stream.
  const ImuProbe& m = report.imu;
  ASSERT_TRUE(m.up) << m.error;
  EXPECT_EQ(m.device, "emu:bmi263@0x68");
  EXPECT_EQ(m.chip_id, 0x24);
  EXPECT_EQ(m.internal_status, 0x01);
  EXPECT_DOUBLE_EQ(m.odr_hz, 800.0);
  EXPECT_DOUBLE_EQ(m.accel_range_g, 8.0);
  EXPECT_DOUBLE_EQ(m.gyro_range_dps, 2000.0);
  EXPECT_NEAR(m.seconds, 3.0, 0.01);
  EXPECT_NEAR(static_cast<double>(m.samples), 2400.0, 3.0);
  EXPECT_NEAR(m.rate_hz, 800.0, 0.5);
  EXPECT_LT(m.max_gap_ms, 1.3);
  EXPECT_EQ(m.missed_samples, 0u);
  EXPECT_NEAR(m.mean_accel_norm_m_s2, kGravity, 0.01);
  EXPECT_NEAR(m.mean_accel_m_s2[2], kGravity, 0.01);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(m.mean_gyro_rad_s[static_cast<std::size_t>(k)], truth_.gyro_rad_s[k], 2e-3) << k;
  }
  EXPECT_NEAR(m.temperature_degc, 31.5, 0.1);
  EXPECT_EQ(m.fault_count, 0u) << (m.faults.empty() ? "" : m.faults.front());

  EXPECT_EQ(report.exitCode(), 0);
  EXPECT_TRUE(report.problems().empty());
}

TEST_F(HardwareProbeTest, TextAndJsonCarryTheFigures) {
  const ServiceConfig cfg = config();
  EmulatedBoard board(cfg.sources.hardware, truth_);
  const ProbeReport report = probe(cfg, board, 1.0);
  ASSERT_EQ(report.exitCode(), 0) << probeReportText(report);

  const std::string text = probeReportText(report);
  EXPECT_NE(text.find("DWM3000 on emu:spidev0.0: up"), std::string::npos) << text;
  EXPECT_NE(text.find("DEV_ID 0xDECA0302 (DW3110)"), std::string::npos) << text;
  EXPECT_NE(text.find("TX 16390 (read back 16390), RX 16380 (read back 16380)"), std::string::npos) << text;
  EXPECT_NE(text.find("BMI263 on emu:bmi263@0x68: up"), std::string::npos) << text;
  EXPECT_NE(text.find("chip id 0x24, INTERNAL_STATUS 0x01 (init_ok)"), std::string::npos) << text;
  EXPECT_NE(text.find("gyro cross-axis correction: off"), std::string::npos) << text;  // the default
  EXPECT_NE(text.find("RX timeout"), std::string::npos) << text;  // anchor 3
  EXPECT_NE(text.find("start-up: LDO trims 0x2A6B4C38/0x00A75C14 and bias 0x13 from OTP; XTAL trim 0x1B from OTP; "
                      "PLL lock "),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("DGC on (driver's table); PGF calibration done"), std::string::npos) << text;
  EXPECT_NE(text.find("first frames: anchor 0 at 2.50"), std::string::npos) << text;
  EXPECT_NE(text.find("probe: OK"), std::string::npos) << text;

  nlohmann::json json = nlohmann::json::parse(probeReportJson(report));  // not const: a missing key reads as null
  EXPECT_EQ(json["ok"], true) << json;
  EXPECT_EQ(json["uwb"]["dev_id"], "0xDECA0302") << json;
  EXPECT_EQ(json["imu"]["chip_id"], "0x24") << json;
  EXPECT_EQ(json["imu"]["internal_status_name"], "init_ok") << json;
  EXPECT_EQ(json["imu"]["gyro_cross_axis"], false) << json;
  EXPECT_TRUE(json["imu"]["gyro_cas"].is_null()) << json;
  // RX level / first-path power from the diagnostics; null for the silent anchor.
  const emu::Dw3000ResponderModel channel;
  nlohmann::json a1 = anchorOf(json, "0x0001"), a2 = anchorOf(json, "0x0002"), a3 = anchorOf(json, "0x0003"),
                 a4 = anchorOf(json, "0x0004");
  ASSERT_FALSE(a1.is_null() || a2.is_null() || a3.is_null() || a4.is_null()) << json;
  EXPECT_NEAR(a1["mean_rssi_dbm"].get<double>(), channel.rx_level_at_1m_dbm - 20.0 * std::log10(2.5), 0.1);
  EXPECT_NEAR(a1["mean_fp_power_dbm"].get<double>(),
              channel.rx_level_at_1m_dbm - 20.0 * std::log10(2.5) - channel.nlos_gap_db(0), 0.1);
  EXPECT_TRUE(a4["mean_rssi_dbm"].is_null()) << a4;
  EXPECT_EQ(json["exit_code"], 0);
  EXPECT_NEAR(a1["mean_range_m"].get<double>(), 2.5, 0.01);
  EXPECT_NEAR(a2["mean_range_m"].get<double>(), 4.0, 0.01);
  EXPECT_NEAR(a3["mean_range_m"].get<double>(), 7.25, 0.01);
  EXPECT_EQ(a4["ranges"], 0);
  EXPECT_GT(a4["errors"]["RX timeout"].get<double>(), 5.0) << a4;
  EXPECT_NEAR(json["imu"]["rate_hz"].get<double>(), 800.0, 1.0);
  EXPECT_NEAR(json["imu"]["mean_accel_norm_m_s2"].get<double>(), kGravity, 0.01);
  EXPECT_NEAR(json["imu"]["odr_hz"].get<double>(), 800.0, 1e-9);
  nlohmann::json& startup = json["uwb"]["startup"];
  EXPECT_EQ(startup["xtal_trim"], "0x1B") << startup;
  EXPECT_EQ(startup["xtal_trim_from_otp"], true) << startup;
  EXPECT_EQ(startup["pgf_done"], true) << startup;
  EXPECT_GT(startup["pll_lock_us"].get<double>(), 0.0);
  ASSERT_FALSE(json["uwb"]["first_frames"].empty()) << json;
  EXPECT_EQ(json["uwb"]["first_frames"][0]["anchor"], 0);
  EXPECT_NEAR(json["uwb"]["first_frames"][0]["range_m"].get<double>(), 2.5, 0.005);
}

TEST_F(HardwareProbeTest, AFailedDiagnosticsReadKeepsTheRangeAndIsListed) {
  const ServiceConfig cfg = config();
  EmulatedBoard board(cfg.sources.hardware, truth_);
  board.dw3000().failReadsOf(0x0C, 0x2C, 2, std::make_error_code(std::errc::io_error));  // IP_DIAG_1 burst
  const ProbeReport report = probe(cfg, board, 1.0);
  ASSERT_TRUE(report.uwb.up) << report.uwb.error;
  std::uint64_t ranges = 0;
  std::uint64_t with_power = 0;
  for (const AnchorProbe& a : report.uwb.anchors) {
    ranges += a.ranges();
    with_power += a.rssi_dbm.count;
    if (a.id != 3) {  // switched off
      EXPECT_EQ(a.ranges(), a.attempts) << a.id;  // every answer counted
    }
  }
  EXPECT_EQ(with_power + 2, ranges);
  ASSERT_EQ(report.uwb.device_faults.size(), 1u);
  EXPECT_EQ(report.uwb.device_faults.begin()->first, "RX diagnostics read failed (range kept)");
  EXPECT_EQ(report.uwb.device_faults.begin()->second, 2u);
  EXPECT_EQ(report.uwb.reinitializations, 0u);
  EXPECT_EQ(report.exitCode(), 0);
}

TEST_F(HardwareProbeTest, WrongDevIdFailsTheUwbNamingTheDeviceAndStillProbesTheImu) {
  const ServiceConfig cfg = config();
  truth_.dev_id = 0x12345678;
  EmulatedBoard board(cfg.sources.hardware, truth_);
  const ProbeReport report = probe(cfg, board, 0.5);
  EXPECT_FALSE(report.uwb.up);
  EXPECT_NE(report.uwb.error.find("emu:spidev0.0"), std::string::npos) << report.uwb.error;
  EXPECT_NE(report.uwb.error.find("0x12345678"), std::string::npos) << report.uwb.error;
  EXPECT_TRUE(report.imu.up) << report.imu.error;
  EXPECT_GT(report.imu.samples, 300u);
  EXPECT_EQ(report.exitCode(), 2);
  ASSERT_FALSE(report.problems().empty());
  EXPECT_NE(report.problems().front().find("emu:spidev0.0"), std::string::npos);
  const std::string text = probeReportText(report);
  EXPECT_NE(text.find("DWM3000 on emu:spidev0.0: FAILED"), std::string::npos) << text;
}

TEST_F(HardwareProbeTest, WrongChipIdFailsTheImuNamingTheDevice) {
  const ServiceConfig cfg = config();
  truth_.chip_id = 0x99;
  EmulatedBoard board(cfg.sources.hardware, truth_);
  const ProbeReport report = probe(cfg, board, 0.5);
  EXPECT_TRUE(report.uwb.up) << report.uwb.error;
  EXPECT_FALSE(report.imu.up);
  EXPECT_EQ(report.imu.chip_id, 0x99);
  EXPECT_NE(report.imu.error.find("emu:bmi263@0x68"), std::string::npos) << report.imu.error;
  EXPECT_EQ(report.exitCode(), 2);
  nlohmann::json json = nlohmann::json::parse(probeReportJson(report));  // not const: a missing key reads as null
  EXPECT_EQ(json["imu"]["chip_id"], "0x99") << json;
  EXPECT_EQ(json["ok"], false) << json;
}

TEST_F(HardwareProbeTest, DevicesThatCouldNotBeOpenedAreReportedWithTheirError) {
  const ServiceConfig cfg = config();
  const std::string uwb_error = "cannot open /dev/spidev0.0 (sources.hardware.uwb.spi_device): no such file";
  const std::string imu_error = "cannot open /dev/i2c-1@0x68 (sources.hardware.imu.i2c_device): no such file";
  const ProbeReport report =
      runProbe(cfg.sources.hardware, UwbProbeTarget{{}, uwb_error}, ImuProbeTarget{{}, imu_error}, ProbeOptions{});
  EXPECT_FALSE(report.uwb.opened);
  EXPECT_FALSE(report.imu.opened);
  EXPECT_EQ(report.exitCode(), 2);
  ASSERT_EQ(report.problems().size(), 2u);
  EXPECT_EQ(report.problems()[0], uwb_error);
  EXPECT_EQ(report.problems()[1], imu_error);
  const std::string text = probeReportText(report);
  EXPECT_NE(text.find("DWM3000 on /dev/spidev0.0: FAILED\n  " + uwb_error), std::string::npos) << text;
  EXPECT_NE(text.find("BMI263 on /dev/i2c-1@0x68: FAILED\n  " + imu_error), std::string::npos) << text;
}

TEST_F(HardwareProbeTest, NoAnchorAnsweringIsExitCodeThree) {
  const ServiceConfig cfg = config();
  truth_.responders.clear();
  EmulatedBoard board(cfg.sources.hardware, truth_);
  const ProbeReport report = probe(cfg, board, 0.5);
  EXPECT_TRUE(report.uwb.up);
  EXPECT_TRUE(report.imu.up);
  EXPECT_EQ(report.exitCode(), 3);
  ASSERT_EQ(report.problems().size(), 1u);
  EXPECT_NE(report.problems()[0].find("no anchor answered"), std::string::npos);
}

TEST_F(HardwareProbeTest, InterruptEndsTheMeasurementEarly) {
  const ServiceConfig cfg = config();
  EmulatedBoard board(cfg.sources.hardware, truth_);
  std::atomic<bool> interrupt{true};
  ProbeOptions options;
  options.seconds = 600.0;
  const ProbeReport report = runProbe(cfg.sources.hardware, UwbProbeTarget{board.uwb(), ""},
                                      ImuProbeTarget{board.imu(), ""}, options, &interrupt);
  EXPECT_TRUE(report.uwb.up);
  EXPECT_LT(report.uwb.seconds, 1.0);
  EXPECT_LT(report.imu.samples, 10u);
}

TEST_F(HardwareProbeTest, RejectsABadMeasurementTime) {
  const ServiceConfig cfg = config();
  ProbeOptions options;
  options.seconds = 0.0;
  EXPECT_THROW(runProbe(cfg.sources.hardware, UwbProbeTarget{{}, "x"}, ImuProbeTarget{{}, "y"}, options),
               std::invalid_argument);
}

TEST(RunningStats, MeanAndSampleStandardDeviation) {
  RunningStats s;
  EXPECT_EQ(s.stddev(), 0.0);
  for (double x : {2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0}) s.add(x);
  EXPECT_DOUBLE_EQ(s.mean, 5.0);
  EXPECT_NEAR(s.stddev(), std::sqrt(32.0 / 7.0), 1e-12);
  EXPECT_DOUBLE_EQ(s.min, 2.0);
  EXPECT_DOUBLE_EQ(s.max, 9.0);
}

}  // namespace
}  // namespace rilo
