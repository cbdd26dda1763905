#pragma once
// BMI263 register-level driver over hal::I2cDevice: bus access with retry and
// back-off, the bring-up sequence (chip id, soft reset, configuration blob
// upload, measurement and interrupt configuration) and the raw reads of the
// data path. Time keeping, fault reporting and the interrupt loop live in
// Bmi263Source; this class never touches a sink.
//
// All waits use hal::Clock, so the driver runs on the VirtualClock against the
// emulator in tests.
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include "hal/bmi263/bmi263_config.h"
#include "hal/bmi263/bmi263_registers.h"
#include "hal/bus/clock.h"
#include "hal/bus/i2c_device.h"

namespace rilo::bmi263 {

struct BringUpResult {
  bool ok = false;
  /// Retrying cannot help (wrong chip id, missing or malformed blob file).
  bool permanent = false;
  std::string error;                 ///< clear text naming the device, file, register values
  std::uint8_t chip_id = 0;
  std::uint8_t internal_status = 0;  ///< last INTERNAL_STATUS read
  bool gyro_cross_axis = false;      ///< the cross-axis correction is applied to every sample
  std::int8_t gyro_cas = 0;          ///< its factor (GYR_CAS, -64..63; x -= cas * z / 512)
};

/// Bosch's gyro cross-axis correction on raw counts: x -= cas * z / 512
/// (integer division, saturated to int16), as the BMI2 API applies it.
void correctGyroCrossAxis(std::array<std::int16_t, 3>& gyro, std::int8_t cas) noexcept;
/// GYR_CAS as read (bits 6:0, two's complement over 7 bits).
std::int8_t decodeGyrCas(std::uint8_t raw) noexcept;

/// One data-ready burst (15 bytes from ACC_DATA_X).
struct RawImuData {
  std::array<std::int16_t, 3> accel{};
  std::array<std::int16_t, 3> gyro{};
  std::uint32_t sensortime = 0;  ///< 24 bit
};

RawImuData decodeDataBurst(std::span<const std::uint8_t, kDataBurstBytes> bytes) noexcept;

class Bmi263Driver {
 public:
  /// `config` must outlive the driver and be valid (validate()).
  Bmi263Driver(hal::I2cDevice& i2c, hal::Clock& clock, const Bmi263Config& config);

  /// Full bring-up. Reads the blob from config.config_blob_path each time.
  BringUpResult bringUp();

  // Data path (retry with back-off inside; on failure lastBusError() says what failed).
  std::error_code readData(RawImuData& out) noexcept;
  std::error_code readFifoLength(std::size_t& bytes) noexcept;
  std::error_code readFifo(std::span<std::uint8_t> out) noexcept;
  std::error_code flushFifo() noexcept;
  /// NaN when the part reports the value as invalid (0x8000).
  std::error_code readTemperature(double& degc) noexcept;

  /// Register access with the configured retries and back-off.
  std::error_code read(std::uint8_t reg, std::span<std::uint8_t> out) noexcept;
  std::error_code write(std::uint8_t reg, std::span<const std::uint8_t> data) noexcept;
  std::error_code writeByte(std::uint8_t reg, std::uint8_t value) noexcept;

  /// "I2C read of 15 bytes at reg 0x0C failed after 4 attempts: Remote I/O
  /// error (errno 121)" for the last failed access (rare path: allocates).
  std::string lastBusError() const;
  std::uint64_t retries() const noexcept { return retries_.load(std::memory_order_relaxed); }
  std::uint64_t failures() const noexcept { return failures_.load(std::memory_order_relaxed); }

  // Conversions for the configured ranges.
  double accelScale() const noexcept { return accel_m_s2_per_lsb_; }  ///< m/s^2 per LSB
  double gyroScale() const noexcept { return gyro_rad_s_per_lsb_; }   ///< rad/s per LSB
  /// The cross-axis factor of the last bring-up, if the correction applies.
  bool gyroCrossAxis() const noexcept { return cross_axis_; }
  std::int8_t gyroCas() const noexcept { return gyro_cas_; }
  const hal::I2cDevice& device() const noexcept { return i2c_; }
  const Bmi263Config& config() const noexcept { return config_; }

 private:
  bool loadBlob(BringUpResult& result);
  bool uploadBlob(BringUpResult& result);
  bool waitInitOk(BringUpResult& result);
  bool configureMeasurement(BringUpResult& result);
  bool readCrossAxisFactor(BringUpResult& result);
  bool fail(BringUpResult& result, const std::string& what);
  std::error_code access(bool is_write, std::uint8_t reg, std::span<std::uint8_t> in,
                         std::span<const std::uint8_t> out) noexcept;

  hal::I2cDevice& i2c_;
  hal::Clock& clock_;
  const Bmi263Config& config_;
  std::vector<std::uint8_t> blob_;
  double accel_m_s2_per_lsb_ = 0.0;
  double gyro_rad_s_per_lsb_ = 0.0;
  bool cross_axis_ = false;
  std::int8_t gyro_cas_ = 0;

  std::atomic<std::uint64_t> retries_{0};
  std::atomic<std::uint64_t> failures_{0};
  // Last failure (kept as plain values so the failing path does not allocate).
  bool last_is_write_ = false;
  std::uint8_t last_reg_ = 0;
  std::size_t last_bytes_ = 0;
  int last_attempts_ = 0;
  std::error_code last_error_;
};

}  // namespace rilo::bmi263
