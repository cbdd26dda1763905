#pragma once
// I2C device (one 7-bit address) seen by a driver: register reads with a
// repeated start and register writes (as i2c-dev's I2C_RDWR). Implemented by
// the i2c-dev back-end on the board and by register-level emulators in tests.
#include <cstdint>
#include <span>
#include <string>
#include <system_error>

namespace rilo::hal {

class I2cDevice {
 public:
  virtual ~I2cDevice() = default;
  /// Write `reg`, repeated start, read out.size() bytes (auto-increment).
  virtual std::error_code readRegisters(std::uint8_t reg, std::span<std::uint8_t> out) noexcept = 0;
  /// Write `reg` followed by data in one message (auto-increment).
  virtual std::error_code writeRegisters(std::uint8_t reg,
                                         std::span<const std::uint8_t> data) noexcept = 0;
  /// "/dev/i2c-1@0x68" or the emulator's name, for error messages.
  virtual const std::string& path() const noexcept = 0;
};

}  // namespace rilo::hal
