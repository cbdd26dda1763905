#include "hal/bmi263/bmi263_config.h"

#include <stdexcept>

#include "hal/bmi263/bmi263_registers.h"

namespace rilo::bmi263 {

void Bmi263Config::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("Bmi263Config." + what); };
  if (accepted_chip_ids.empty()) fail("accepted_chip_ids: list at least one CHIP_ID");
  if (config_blob_path.empty()) fail("config_blob_path: required (path of Bosch's configuration blob)");
  if (expected_blob_bytes % 2 != 0) fail("expected_blob_bytes: must be even (INIT_ADDR counts 16-bit words)");
  if (expected_blob_bytes > 2 * 4096) fail("expected_blob_bytes: at most 8192 (12-bit word address)");
  if (blob_burst_bytes < 2 || blob_burst_bytes % 2 != 0 || blob_burst_bytes > 8190) {
    fail("blob_burst_bytes: must be even and in [2, 8190]");
  }
  if (fifo_watermark_frames < 1 || fifo_watermark_frames * fifo::kAccGyrFrameBytes > 1024) {
    fail("fifo_watermark_frames: must be in [1, 78] (watermark of at most 1024 bytes)");
  }
  if (fifo_read_max_bytes < (fifo_watermark_frames + 1) * fifo::kAccGyrFrameBytes + fifo::kSensorTimeFrameBytes ||
      fifo_read_max_bytes > 8192) {
    fail("fifo_read_max_bytes: must hold the watermark plus one frame and the sensortime frame, and be <= 8192");
  }
  if (i2c_retries < 0 || i2c_retries > 20) fail("i2c_retries: must be in [0, 20]");
  if (i2c_backoff_ns < 0 || i2c_backoff_ns > 1'000'000'000) fail("i2c_backoff_ns: must be in [0, 1 s]");
  if (soft_reset_wait_ns < 0) fail("soft_reset_wait_ns: must not be negative");
  if (power_conf_wait_ns < 0) fail("power_conf_wait_ns: must not be negative");
  if (init_wait_ns < 0) fail("init_wait_ns: must not be negative");
  if (init_poll_ns <= 0) fail("init_poll_ns: must be positive");
  if (init_timeout_ns < init_wait_ns) fail("init_timeout_ns: must be at least init_wait_ns");
  if (sensor_startup_ns < 0) fail("sensor_startup_ns: must not be negative");
  if (bring_up_attempts < 1) fail("bring_up_attempts: must be at least 1");
  if (irq_timeout_ns <= 0) fail("irq_timeout_ns: must be positive");
  if (max_consecutive_irq_timeouts < 1) fail("max_consecutive_irq_timeouts: must be at least 1");
  if (max_consecutive_read_failures < 1) fail("max_consecutive_read_failures: must be at least 1");
  if (max_consecutive_irq_errors < 1) fail("max_consecutive_irq_errors: must be at least 1");
  if (irq_error_backoff_ns < 0) fail("irq_error_backoff_ns: must not be negative");
  if (temperature_period_ns < 0) fail("temperature_period_ns: must not be negative (0 = never)");
  if (pairing_tolerance_ns < 40'000 || pairing_tolerance_ns > 300'000) {
    fail("pairing_tolerance_ns: must be in [40 us, 300 us] (above the 39 us tick, below half a period at 1600 Hz)");
  }
  time_fit.validate();
}

std::uint8_t odrCode(Odr odr) { return odr == Odr::k800Hz ? odr::k800Hz : odr::k1600Hz; }
double odrHz(Odr odr) { return odr == Odr::k800Hz ? 800.0 : 1600.0; }
std::int64_t periodTicks(Odr odr) { return odr::periodTicks(odrCode(odr)); }

std::uint8_t accelRangeCode(AccelRange range) { return static_cast<std::uint8_t>(range); }

std::uint8_t gyroRangeCode(GyroRange range) {
  // GYR_RANGE counts down from 2000 dps (code 0) to 125 dps (code 4).
  return static_cast<std::uint8_t>(4 - static_cast<int>(range));
}

double accelRangeG(AccelRange range) { return 2.0 * static_cast<double>(1 << static_cast<int>(range)); }
double gyroRangeDps(GyroRange range) { return 125.0 * static_cast<double>(1 << static_cast<int>(range)); }
double accelLsbPerG(AccelRange range) { return 32768.0 / accelRangeG(range); }
double gyroLsbPerDps(GyroRange range) { return 32768.0 / gyroRangeDps(range); }

const char* toString(Odr odr) { return odr == Odr::k800Hz ? "800 Hz" : "1600 Hz"; }
const char* toString(InterruptMode mode) {
  return mode == InterruptMode::kDataReady ? "data-ready" : "FIFO watermark";
}

const char* toString(GyroCrossAxis mode) {
  switch (mode) {
    case GyroCrossAxis::kAuto: return "auto";
    case GyroCrossAxis::kOn: return "on";
    case GyroCrossAxis::kOff: return "off";
  }
  return "?";
}

}  // namespace rilo::bmi263
