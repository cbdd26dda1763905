#pragma once
// Configuration of the BMI263 driver: part identity, the configuration blob's
// file, measurement settings, interrupt mode, bus retry policy, timeouts and
// the time fit. Defaults follow shared/docs/hardware-notes.md; the ones marked
// UNVERIFIED must be checked on the board (hal/bmi263/README.md).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hal/bmi263/sensor_time_fit.h"

namespace rilo::bmi263 {

enum class Odr { k800Hz, k1600Hz };                   ///< performance mode, accel and gyro alike
enum class AccelRange { k2g, k4g, k8g, k16g };
enum class GyroRange { k125dps, k250dps, k500dps, k1000dps, k2000dps };
enum class InterruptMode {
  kDataReady,      ///< INT1 on every sample; burst-read data + SENSORTIME (15 bytes)
  kFifoWatermark,  ///< INT1 when the FIFO holds fifo_watermark_frames; read frames + sensortime frame
};

inline constexpr std::uint8_t kChipIdBmi270 = 0x24;
inline constexpr std::uint8_t kChipIdBmi260 = 0x27;

enum class GyroCrossAxis : std::uint8_t { kAuto, kOn, kOff };
const char* toString(GyroCrossAxis mode);

struct Bmi263Config {
  /// CHIP_ID values accepted. 0x24: BMI270 (Bosch BMI270_SensorAPI
  /// bmi270.h BMI270_CHIP_ID; Linux bmi270_core.c, Zephyr bmi270.h). 0x27:
  /// BMI260 (Linux bmi270_core.c BMI260_CHIP_ID_VAL, chrome-ec
  /// accelgyro_bmi260.h). The BMI263's own id is in no public Bosch, Linux or
  /// Zephyr source; one Android context-hub driver names BMI263_CHIP_ID with
  /// a comment "0xA0" (UNVERIFIED, not accepted): add the id read from a part
  /// here (config key imu.bmi263.accepted_chip_ids).
  std::vector<std::uint8_t> accepted_chip_ids{kChipIdBmi270, kChipIdBmi260};
  /// Gyro cross-axis correction (Bosch's BMI2 API: x -= GYR_CAS * z / 512,
  /// the factor read from the part after its configuration is loaded).
  /// kAuto: on for the BMI270's id, whose API applies it; kOn: always; kOff
  /// (the default): the BMI263 is not known to carry the factor at the
  /// BMI270's place (its feature pages differ), and its id is unknown, so a
  /// BMI263 reading 0x24 would get a wrong correction under kAuto.
  GyroCrossAxis gyro_cross_axis = GyroCrossAxis::kOff;
  /// Bosch's configuration blob for this part, read at every bring-up. Never
  /// embedded in the source. Required.
  std::string config_blob_path;
  std::size_t expected_blob_bytes = 8192;  ///< file size check (0: any non-empty even size)
  std::size_t blob_burst_bytes = 256;      ///< bytes per INIT_DATA write (even; adapter limits apply)

  Odr odr = Odr::k800Hz;
  AccelRange accel_range = AccelRange::k8g;
  GyroRange gyro_range = GyroRange::k2000dps;
  InterruptMode interrupt_mode = InterruptMode::kDataReady;
  std::size_t fifo_watermark_frames = 8;   ///< FIFO mode: frames (13 bytes each) per interrupt
  std::size_t fifo_read_max_bytes = 1024;  ///< FIFO mode: largest FIFO_DATA read (buffer allocated once)

  int i2c_retries = 3;                     ///< extra attempts after a failed transfer
  std::int64_t i2c_backoff_ns = 200'000;   ///< wait before the first retry, doubled per retry

  std::int64_t soft_reset_wait_ns = 2'000'000;
  std::int64_t power_conf_wait_ns = 450'000;
  std::int64_t init_wait_ns = 20'000'000;      ///< after INIT_CTRL = 1, before the first poll
  std::int64_t init_poll_ns = 5'000'000;
  std::int64_t init_timeout_ns = 150'000'000;  ///< INTERNAL_STATUS must read init_ok by then
  std::int64_t sensor_startup_ns = 50'000'000; ///< after PWR_CTRL (gyro start-up; UNVERIFIED)
  int bring_up_attempts = 3;                   ///< per (re)start; then the source fails

  std::int64_t irq_timeout_ns = 100'000'000;   ///< no edge this long: fault (and level check)
  int max_consecutive_irq_timeouts = 5;        ///< then re-bring-up
  int max_consecutive_read_failures = 10;      ///< data reads failed after retries: re-bring-up
  int max_consecutive_irq_errors = 10;         ///< GPIO wait errors: then the source fails
  std::int64_t irq_error_backoff_ns = 10'000'000;

  std::int64_t temperature_period_ns = 1'000'000'000;  ///< 0: never read the temperature
  /// Subtracted from fitted sample times: the constant part of the latency
  /// between the sample instant and the kernel's edge stamp (minimum IRQ
  /// latency, data-ready delay). UNVERIFIED: measure on the board.
  std::int64_t sample_time_offset_ns = 0;
  /// An edge is used for the time fit only if, paired with the sample the
  /// read returned, its implied latency is at least -pairing_tolerance_ns
  /// (covers SENSORTIME quantization, 39 us; rejects edges of an earlier sample).
  std::int64_t pairing_tolerance_ns = 100'000;
  SensorTimeFitConfig time_fit;

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

std::uint8_t odrCode(Odr odr);
double odrHz(Odr odr);
std::int64_t periodTicks(Odr odr);           ///< sensortime ticks per sample (32 at 800 Hz)
std::uint8_t accelRangeCode(AccelRange range);  ///< ACC_RANGE 0..3
std::uint8_t gyroRangeCode(GyroRange range);    ///< GYR_RANGE 0..4 (0 = 2000 dps)
double accelRangeG(AccelRange range);
double gyroRangeDps(GyroRange range);
double accelLsbPerG(AccelRange range);       ///< 16384 at 2 g, halving per step
double gyroLsbPerDps(GyroRange range);       ///< 16.384 at 2000 dps, doubling per step
const char* toString(Odr odr);
const char* toString(InterruptMode mode);

}  // namespace rilo::bmi263
