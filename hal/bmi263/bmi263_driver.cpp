#include "hal/bmi263/bmi263_driver.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>

namespace rilo::bmi263 {
namespace {

std::string hex2(unsigned value) {
  char text[8];
  std::snprintf(text, sizeof text, "0x%02X", value & 0xFFu);
  return text;
}

std::int16_t le16(const std::uint8_t* p) noexcept {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0] | (p[1] << 8)));
}

}  // namespace

RawImuData decodeDataBurst(std::span<const std::uint8_t, kDataBurstBytes> bytes) noexcept {
  RawImuData raw;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    raw.accel[axis] = le16(bytes.data() + 2 * axis);
    raw.gyro[axis] = le16(bytes.data() + 6 + 2 * axis);
  }
  raw.sensortime = static_cast<std::uint32_t>(bytes[12]) | (static_cast<std::uint32_t>(bytes[13]) << 8) |
                   (static_cast<std::uint32_t>(bytes[14]) << 16);
  return raw;
}

Bmi263Driver::Bmi263Driver(hal::I2cDevice& i2c, hal::Clock& clock, const Bmi263Config& config)
    : i2c_(i2c), clock_(clock), config_(config) {
  accel_m_s2_per_lsb_ = kStandardGravity / accelLsbPerG(config_.accel_range);
  gyro_rad_s_per_lsb_ = (std::numbers::pi / 180.0) / gyroLsbPerDps(config_.gyro_range);
}

// ---------------------------------------------------------------------------
// Bus access

std::error_code Bmi263Driver::access(bool is_write, std::uint8_t reg, std::span<std::uint8_t> in,
                                     std::span<const std::uint8_t> out) noexcept {
  std::error_code error;
  std::int64_t backoff_ns = config_.i2c_backoff_ns;
  const int attempts = 1 + config_.i2c_retries;
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    error = is_write ? i2c_.writeRegisters(reg, out) : i2c_.readRegisters(reg, in);
    if (!error) return {};
    if (attempt == attempts) break;
    retries_.fetch_add(1, std::memory_order_relaxed);
    // NACK (device busy, e.g. right after reset) and timeouts are transient:
    // wait, doubling the wait each time, then try again.
    clock_.sleepForNs(backoff_ns);
    backoff_ns = std::min<std::int64_t>(backoff_ns * 2, 1'000'000'000);
  }
  failures_.fetch_add(1, std::memory_order_relaxed);
  last_is_write_ = is_write;
  last_reg_ = reg;
  last_bytes_ = is_write ? out.size() : in.size();
  last_attempts_ = attempts;
  last_error_ = error;
  return error;
}

std::error_code Bmi263Driver::read(std::uint8_t reg, std::span<std::uint8_t> out) noexcept {
  return access(false, reg, out, {});
}

std::error_code Bmi263Driver::write(std::uint8_t reg, std::span<const std::uint8_t> data) noexcept {
  return access(true, reg, {}, data);
}

std::error_code Bmi263Driver::writeByte(std::uint8_t reg, std::uint8_t value) noexcept {
  const std::uint8_t data[1] = {value};
  return write(reg, data);
}

std::string Bmi263Driver::lastBusError() const {
  return std::string("I2C ") + (last_is_write_ ? "write" : "read") + " of " + std::to_string(last_bytes_) +
         " byte" + (last_bytes_ == 1 ? "" : "s") + " at reg " + hex2(last_reg_) + " failed after " +
         std::to_string(last_attempts_) + " attempt" + (last_attempts_ == 1 ? "" : "s") + ": " +
         last_error_.message() + " (errno " + std::to_string(last_error_.value()) + ")";
}

// ---------------------------------------------------------------------------
// Bring-up

bool Bmi263Driver::fail(BringUpResult& result, const std::string& what) {
  result.ok = false;
  result.error = "BMI263 at " + i2c_.path() + ": " + what;
  return false;
}

bool Bmi263Driver::loadBlob(BringUpResult& result) {
  const std::string& path = config_.config_blob_path;
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) {
    const int err = errno;
    result.permanent = true;
    return fail(result, "cannot read configuration blob '" + path + "' (Bmi263Config.config_blob_path): " +
                            std::strerror(err));
  }
  blob_.clear();
  std::uint8_t chunk[4096];
  std::size_t n = 0;
  while ((n = std::fread(chunk, 1, sizeof chunk, file)) > 0) {
    blob_.insert(blob_.end(), chunk, chunk + n);
    if (blob_.size() > 8192) break;
  }
  const bool read_error = std::ferror(file) != 0;
  std::fclose(file);
  result.permanent = true;
  if (read_error) return fail(result, "error reading configuration blob '" + path + "'");
  if (blob_.empty()) return fail(result, "configuration blob '" + path + "' is empty");
  if (config_.expected_blob_bytes != 0 && blob_.size() != config_.expected_blob_bytes) {
    return fail(result, "configuration blob '" + path + "' has " +
                            (blob_.size() > 8192 ? std::string("more than 8192") : std::to_string(blob_.size())) +
                            " bytes, expected " + std::to_string(config_.expected_blob_bytes) +
                            " (Bmi263Config.expected_blob_bytes): is it the blob for this part?");
  }
  if (blob_.size() % 2 != 0 || blob_.size() > 8192) {
    return fail(result, "configuration blob '" + path + "' has " + std::to_string(blob_.size()) +
                            " bytes; the part takes an even size of at most 8192");
  }
  result.permanent = false;
  return true;
}

bool Bmi263Driver::uploadBlob(BringUpResult& result) {
  for (std::size_t offset = 0; offset < blob_.size(); offset += config_.blob_burst_bytes) {
    const std::size_t n = std::min(config_.blob_burst_bytes, blob_.size() - offset);
    // INIT_ADDR counts 16-bit words: bits 3:0 in INIT_ADDR_0, bits 11:4 in INIT_ADDR_1.
    const std::size_t word = offset / 2;
    const std::uint8_t addr[2] = {static_cast<std::uint8_t>(word & 0x0F), static_cast<std::uint8_t>(word >> 4)};
    if (write(reg::kInitAddr0, addr)) {
      return fail(result, "configuration upload of '" + config_.config_blob_path + "' failed at byte " +
                              std::to_string(offset) + ": " + lastBusError());
    }
    if (write(reg::kInitData, std::span<const std::uint8_t>(blob_.data() + offset, n))) {
      return fail(result, "configuration upload of '" + config_.config_blob_path + "' failed at byte " +
                              std::to_string(offset) + ": " + lastBusError());
    }
  }
  return true;
}

bool Bmi263Driver::waitInitOk(BringUpResult& result) {
  clock_.sleepForNs(config_.init_wait_ns);
  const std::int64_t deadline_ns = clock_.nowNs() + (config_.init_timeout_ns - config_.init_wait_ns);
  for (;;) {
    std::uint8_t status = 0;
    if (read(reg::kInternalStatus, std::span<std::uint8_t>(&status, 1))) {
      return fail(result, "reading INTERNAL_STATUS after the configuration upload: " + lastBusError());
    }
    result.internal_status = status;
    const std::uint8_t message = status & internal_status::kMask;
    if (message == internal_status::kInitOk) return true;
    if (message != internal_status::kNotInit) {
      return fail(result, "configuration load failed: INTERNAL_STATUS " + hex2(status) + " (" +
                              internal_status::name(status) + ") after uploading '" + config_.config_blob_path +
                              "' (" + std::to_string(blob_.size()) + " bytes): is it the blob for this part?");
    }
    if (clock_.nowNs() >= deadline_ns) {
      return fail(result, "configuration load timed out: INTERNAL_STATUS still " + hex2(status) + " (" +
                              internal_status::name(status) + ") " +
                              std::to_string(config_.init_timeout_ns / 1'000'000) + " ms after uploading '" +
                              config_.config_blob_path + "' (" + std::to_string(blob_.size()) + " bytes)");
    }
    clock_.sleepForNs(config_.init_poll_ns);
  }
}

bool Bmi263Driver::configureMeasurement(BringUpResult& result) {
  const std::uint8_t odr = odrCode(config_.odr);
  const std::uint8_t conf[4] = {
      static_cast<std::uint8_t>(bits::kAccConfPerformance | odr),
      accelRangeCode(config_.accel_range),
      static_cast<std::uint8_t>(bits::kGyrConfPerformance | odr),
      gyroRangeCode(config_.gyro_range),
  };
  if (write(reg::kAccConf, conf)) return fail(result, "writing ACC_CONF..GYR_RANGE: " + lastBusError());
  std::uint8_t readback[4] = {};
  if (read(reg::kAccConf, readback)) return fail(result, "reading back ACC_CONF..GYR_RANGE: " + lastBusError());
  static const char* const kNames[4] = {"ACC_CONF", "ACC_RANGE", "GYR_CONF", "GYR_RANGE"};
  for (std::size_t i = 0; i < 4; ++i) {
    if (readback[i] != conf[i]) {
      return fail(result, std::string("configuration not applied: ") + kNames[i] + " reads " + hex2(readback[i]) +
                              ", wrote " + hex2(conf[i]));
    }
  }

  const bool fifo_mode = config_.interrupt_mode == InterruptMode::kFifoWatermark;
  if (fifo_mode) {
    const std::size_t watermark = config_.fifo_watermark_frames * fifo::kAccGyrFrameBytes;
    const std::uint8_t wtm[2] = {static_cast<std::uint8_t>(watermark & 0xFF),
                                 static_cast<std::uint8_t>((watermark >> 8) & 0x1F)};
    // Stream mode (oldest frames dropped when full, reported by skip frames),
    // sensortime frame after the last frame; headers, accel and gyro.
    const std::uint8_t fifo_cfg[2] = {bits::kFifoConfig0TimeEn, static_cast<std::uint8_t>(
                                                                    bits::kFifoConfig1HeaderEn |
                                                                    bits::kFifoConfig1AccEn |
                                                                    bits::kFifoConfig1GyrEn)};
    if (writeByte(reg::kFifoDowns, bits::kFifoDownsFiltered) || write(reg::kFifoWtm0, wtm) ||
        write(reg::kFifoConfig0, fifo_cfg)) {
      return fail(result, "configuring the FIFO: " + lastBusError());
    }
  } else {
    const std::uint8_t fifo_off[2] = {0x00, 0x00};
    if (write(reg::kFifoConfig0, fifo_off)) return fail(result, "disabling the FIFO: " + lastBusError());
  }
  const std::uint8_t map = fifo_mode ? bits::kIntMapFwmInt1 : bits::kIntMapDrdyInt1;
  if (writeByte(reg::kInt1IoCtrl, bits::kInt1PushPullActiveHigh) || writeByte(reg::kIntLatch, 0x00) ||
      writeByte(reg::kIntMapData, map)) {
    return fail(result, "configuring INT1: " + lastBusError());
  }
  if (writeByte(reg::kPwrCtrl, bits::kPwrCtrlAccGyrTemp)) {
    return fail(result, "enabling accel, gyro and temperature (PWR_CTRL): " + lastBusError());
  }
  clock_.sleepForNs(config_.sensor_startup_ns);
  if (fifo_mode && flushFifo()) return fail(result, "flushing the FIFO: " + lastBusError());
  return true;
}

std::int8_t decodeGyrCas(std::uint8_t raw) noexcept {
  const int v = raw & 0x7F;
  return static_cast<std::int8_t>((v & 0x40) != 0 ? v - 128 : v);
}

void correctGyroCrossAxis(std::array<std::int16_t, 3>& gyro, std::int8_t cas) noexcept {
  const std::int32_t x = gyro[0] - static_cast<std::int16_t>(static_cast<std::int32_t>(cas) * gyro[2] / 512);
  gyro[0] = static_cast<std::int16_t>(std::clamp<std::int32_t>(x, -32768, 32767));
}

bool Bmi263Driver::readCrossAxisFactor(BringUpResult& result) {
  // After the configuration blob: the factor lives in the feature memory it
  // sets up (page 0, offset 0x0C, as bmi2_get_gyro_cross_sense reads it).
  cross_axis_ = false;
  gyro_cas_ = 0;
  const bool wanted = config_.gyro_cross_axis == GyroCrossAxis::kOn ||
                      (config_.gyro_cross_axis == GyroCrossAxis::kAuto && result.chip_id == kChipIdBmi270);
  if (!wanted) return true;
  std::uint8_t raw = 0;
  if (writeByte(reg::kFeatPage, 0x00) || read(reg::kGyrCas, std::span<std::uint8_t>(&raw, 1))) {
    return fail(result, "reading the gyro cross-axis factor (FEAT_PAGE 0, GYR_CAS 0x3C): " + lastBusError());
  }
  gyro_cas_ = decodeGyrCas(raw);
  cross_axis_ = true;
  result.gyro_cross_axis = true;
  result.gyro_cas = gyro_cas_;
  return true;
}

BringUpResult Bmi263Driver::bringUp() {
  BringUpResult result;
  if (!loadBlob(result)) return result;

  std::uint8_t chip_id = 0;
  if (read(reg::kChipId, std::span<std::uint8_t>(&chip_id, 1))) {
    fail(result, "reading CHIP_ID: " + lastBusError());
    return result;
  }
  result.chip_id = chip_id;
  if (std::find(config_.accepted_chip_ids.begin(), config_.accepted_chip_ids.end(), chip_id) ==
      config_.accepted_chip_ids.end()) {
    std::string accepted;
    for (const std::uint8_t id : config_.accepted_chip_ids) accepted += (accepted.empty() ? "" : ", ") + hex2(id);
    result.permanent = true;
    fail(result, "unexpected CHIP_ID " + hex2(chip_id) + "; accepted: " + accepted +
                     " (Bmi263Config.accepted_chip_ids)");
    return result;
  }

  // Soft reset. The part may reset before it acknowledges the command, so a
  // failed write here is expected on some boards: one attempt, error ignored.
  const std::uint8_t reset_cmd[1] = {cmd::kSoftReset};
  (void)i2c_.writeRegisters(reg::kCmd, reset_cmd);
  clock_.sleepForNs(config_.soft_reset_wait_ns);
  std::uint8_t id_after_reset = 0;
  if (read(reg::kChipId, std::span<std::uint8_t>(&id_after_reset, 1))) {
    fail(result, "no answer after soft reset: " + lastBusError());
    return result;
  }
  if (id_after_reset != chip_id) {
    fail(result, "CHIP_ID changed across soft reset: " + hex2(chip_id) + " then " + hex2(id_after_reset));
    return result;
  }

  // Advanced power save off (burst writes of the blob need it), then load.
  if (writeByte(reg::kPwrConf, 0x00)) {
    fail(result, "writing PWR_CONF: " + lastBusError());
    return result;
  }
  clock_.sleepForNs(config_.power_conf_wait_ns);
  if (writeByte(reg::kInitCtrl, 0x00)) {
    fail(result, "writing INIT_CTRL = 0: " + lastBusError());
    return result;
  }
  if (!uploadBlob(result)) return result;
  if (writeByte(reg::kInitCtrl, 0x01)) {
    fail(result, "writing INIT_CTRL = 1: " + lastBusError());
    return result;
  }
  if (!waitInitOk(result)) return result;
  if (!readCrossAxisFactor(result)) return result;
  if (!configureMeasurement(result)) return result;
  result.ok = true;
  return result;
}

// ---------------------------------------------------------------------------
// Data path

std::error_code Bmi263Driver::readData(RawImuData& out) noexcept {
  std::array<std::uint8_t, kDataBurstBytes> bytes{};
  if (const std::error_code error = read(reg::kAccDataX, bytes)) return error;
  out = decodeDataBurst(bytes);
  return {};
}

std::error_code Bmi263Driver::readFifoLength(std::size_t& bytes) noexcept {
  std::uint8_t length[2] = {};
  if (const std::error_code error = read(reg::kFifoLength0, length)) return error;
  bytes = static_cast<std::size_t>(length[0]) | (static_cast<std::size_t>(length[1] & 0x3F) << 8);
  return {};
}

std::error_code Bmi263Driver::readFifo(std::span<std::uint8_t> out) noexcept { return read(reg::kFifoData, out); }

std::error_code Bmi263Driver::flushFifo() noexcept { return writeByte(reg::kCmd, cmd::kFifoFlush); }

std::error_code Bmi263Driver::readTemperature(double& degc) noexcept {
  std::uint8_t bytes[2] = {};
  if (const std::error_code error = read(reg::kTemperature0, bytes)) return error;
  const auto raw = static_cast<std::uint16_t>(bytes[0] | (bytes[1] << 8));
  degc = raw == 0x8000 ? std::numeric_limits<double>::quiet_NaN()
                       : static_cast<double>(static_cast<std::int16_t>(raw)) / 512.0 + 23.0;
  return {};
}

}  // namespace rilo::bmi263
