#pragma once
// i2c-dev back-end of hal::I2cDevice: one 7-bit device on /dev/i2c-N, register
// reads as an I2C_RDWR message pair joined by a repeated start, register
// writes as one message. Thin on purpose: it is reviewed here and exercised on
// the board (no i2c-dev nodes on development and CI machines).
//
// Not thread-safe: one driver thread owns the device. No allocation per
// transfer (the write buffer is allocated once).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include "hal/bus/i2c_device.h"

namespace rilo::hal {

class I2cLinux final : public I2cDevice {
 public:
  /// i2c-dev rejects messages longer than this (drivers/i2c/i2c-dev.c).
  static constexpr std::size_t kKernelMaxMessageBytes = 8192;

  /// Opens `bus_path` ("/dev/i2c-1") for the device at `address` (7 bit,
  /// 0x08..0x77). `max_message_bytes` (2..8192, register byte included)
  /// bounds one write message: longer writes are split (see writeRegisters).
  /// Throws std::invalid_argument naming the bad parameter, std::runtime_error
  /// with the path and strerror text when the node cannot be opened or is not
  /// an I2C adapter with plain-I2C (I2C_RDWR) support.
  I2cLinux(std::string bus_path, std::uint8_t address,
           std::size_t max_message_bytes = kKernelMaxMessageBytes);
  ~I2cLinux() override;
  I2cLinux(const I2cLinux&) = delete;
  I2cLinux& operator=(const I2cLinux&) = delete;

  /// One I2C_RDWR with two messages: write `reg`, repeated start, read
  /// out.size() bytes. Reads are never split (a split read of a data port
  /// such as FIFO_DATA would re-address it): more than kKernelMaxMessageBytes
  /// returns std::errc::message_size. Errors carry the ioctl's errno
  /// (ENXIO/EREMOTEIO/EIO for a NACK depending on the adapter, ETIMEDOUT,
  /// EAGAIN for arbitration loss).
  std::error_code readRegisters(std::uint8_t reg, std::span<std::uint8_t> out) noexcept override;
  /// One message `reg, data...`. Writes longer than max_message_bytes - 1 are
  /// split into several messages, each re-addressed at reg + offset (the
  /// auto-increment the contract promises). Callers writing a data port
  /// (e.g. the BMI's INIT_DATA) must keep each write within one message.
  std::error_code writeRegisters(std::uint8_t reg, std::span<const std::uint8_t> data) noexcept override;
  /// "/dev/i2c-1@0x68".
  const std::string& path() const noexcept override { return path_; }

 private:
  std::error_code transferOne(std::uint8_t reg, std::span<const std::uint8_t> chunk) noexcept;

  std::string path_;
  std::uint16_t address_;
  int fd_ = -1;
  std::vector<std::uint8_t> write_buffer_;  // register byte + one chunk
};

}  // namespace rilo::hal
