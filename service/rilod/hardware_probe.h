#pragma once
// Bring-up check of the board's devices (`rilo probe`): brings up the DWM3000
// and the BMI263 on the given buses, reports what they say (DEV_ID, channel,
// antenna delays, status; chip id, INTERNAL_STATUS, rate and ranges), then
// measures for a few seconds: SS-TWR to each configured anchor in turn (count,
// success rate, range mean/std, RSSI / first-path power, errors by kind) and
// the IMU stream (rate from the host timestamps, mean |accel|, mean gyro).
//
// Works on the bus interfaces only, so the same code runs on the Linux
// back-ends and against the register-level emulators in tests. The two
// measurements run concurrently (the IMU in a second thread): the two clocks
// must be the same thread-safe clock (CLOCK_MONOTONIC) or two independent
// ones (one virtual clock per emulator).
#include <array>
#include <atomic>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "hal/dw3000/bring_up.h"
#include "hal/dw3000/rx_power.h"
#include "rilod/config.h"
#include "rilod/hardware_sources.h"

namespace rilo {

struct ProbeOptions {
  double seconds = 3.0;  ///< measurement time per device (s), > 0
};

/// Running mean / standard deviation (Welford).
struct RunningStats {
  std::uint64_t count = 0;
  double mean = 0.0;
  double m2 = 0.0;
  double min = std::numeric_limits<double>::infinity();
  double max = -std::numeric_limits<double>::infinity();
  void add(double x) noexcept;
  double stddev() const noexcept;  ///< sample standard deviation (0 below two values)
};

struct AnchorProbe {
  std::uint32_t id = 0;
  std::uint16_t short_address = 0;
  std::uint64_t attempts = 0;  ///< polls sent to this anchor
  RunningStats range_m;        ///< good exchanges
  RunningStats rssi_dbm;       ///< good exchanges with diagnostics
  RunningStats fp_power_dbm;
  RunningStats clock_offset_ppm;
  std::map<std::string, std::uint64_t> errors;  ///< failed exchanges by kind ("RX timeout": 3)
  std::uint64_t ranges() const noexcept { return range_m.count; }
  double successRate() const noexcept;
};

/// A good exchange's CIA diagnostics, as read (the first few of a probe).
struct FrameDiagnostics {
  std::uint32_t anchor_id = 0;
  double range_m = 0.0;
  dw3000::RxDiagnostics raw;
  double rssi_dbm = std::numeric_limits<double>::quiet_NaN();
  double fp_power_dbm = std::numeric_limits<double>::quiet_NaN();
};

struct UwbProbe {
  bool opened = false;  ///< buses available
  bool up = false;      ///< bring-up succeeded
  std::string device;   ///< SPI device path
  std::string error;    ///< open / bring-up failure (names the device), empty if none
  // Bring-up
  std::uint32_t dev_id = 0;
  int channel = 0;
  int preamble_code = 0;
  int preamble_length = 0;
  std::string data_rate;
  std::uint16_t tx_antenna_delay = 0;  ///< configured (device units)
  std::uint16_t rx_antenna_delay = 0;
  std::uint16_t tx_antenna_delay_read = 0;  ///< read back from TX_ANTD / CIA_CONF
  std::uint16_t rx_antenna_delay_read = 0;
  bool spi_crc = false;
  std::uint32_t sys_status = 0;  ///< after bring-up
  std::uint32_t sys_state = 0;
  std::uint32_t irq_mask = 0;
  std::string clock_offset_source;
  double reply_delay_us = 0.0;
  /// The start-up's OTP trims and their source, PLL lock time, DGC and PGF
  /// calibration (also after a failed bring-up, as far as it got).
  dw3000::BringUpReport startup;
  // Measurement
  std::vector<FrameDiagnostics> first_frames;  ///< the first three good exchanges
  double seconds = 0.0;  ///< measured time (s)
  std::vector<AnchorProbe> anchors;
  std::map<std::string, std::uint64_t> device_faults;  ///< SPI / IRQ / TX faults by kind
  std::uint64_t reinitializations = 0;
};

struct ImuProbe {
  bool opened = false;
  bool up = false;
  std::string device;  ///< "/dev/i2c-1@0x68"
  std::string error;
  // Bring-up
  std::uint8_t chip_id = 0;
  std::uint8_t internal_status = 0;
  double odr_hz = 0.0;
  double accel_range_g = 0.0;
  double gyro_range_dps = 0.0;
  std::string interrupt_mode;
  bool gyro_cross_axis = false;  ///< Bosch's cross-axis correction applied
  int gyro_cas = 0;              ///< its factor (GYR_CAS)
  // Measurement (host timestamps from the sensortime fit)
  double seconds = 0.0;  ///< first to last sample (s)
  std::uint64_t samples = 0;
  double rate_hz = 0.0;  ///< (samples - 1) / seconds
  double max_gap_ms = 0.0;
  double mean_accel_norm_m_s2 = 0.0;  ///< mean of |accel| (9.81 at rest)
  std::array<double, 3> mean_accel_m_s2{};
  std::array<double, 3> mean_gyro_rad_s{};
  double temperature_degc = std::numeric_limits<double>::quiet_NaN();
  std::uint64_t missed_samples = 0;
  std::uint64_t i2c_retries = 0;
  std::uint64_t i2c_failures = 0;
  std::uint64_t recoveries = 0;
  std::vector<std::string> faults;  ///< fault messages (first few)
  std::uint64_t fault_count = 0;
};

struct ProbeReport {
  UwbProbe uwb;
  ImuProbe imu;
  /// 0: both devices up and measuring (a range from at least one anchor,
  /// IMU samples); 2: a device could not be opened or brought up; 3: up but
  /// nothing measured (no anchor answered, or no IMU sample).
  int exitCode() const noexcept;
  /// One line per problem (names the device); empty when exitCode() is 0.
  std::vector<std::string> problems() const;
};

/// What the probe is given for one device: its buses, or why they could not
/// be opened (HardwareOpenError text).
struct UwbProbeTarget {
  UwbBuses buses;
  std::string open_error;  ///< non-empty: not opened
};
struct ImuProbeTarget {
  ImuBuses buses;
  std::string open_error;
};

/// Probes both devices. `interrupt` (may be null) ends the measurement early
/// (SIGINT). Throws std::invalid_argument for bad options; device trouble is
/// reported in the result, never thrown.
ProbeReport runProbe(const HardwareSourceConfig& config, const UwbProbeTarget& uwb, const ImuProbeTarget& imu,
                     const ProbeOptions& options, const std::atomic<bool>* interrupt = nullptr);

/// The report for people (what `rilo probe` prints).
std::string probeReportText(const ProbeReport& report);
/// The report as one JSON object (`rilo probe --json`); unknown values are null.
std::string probeReportJson(const ProbeReport& report);

}  // namespace rilo
