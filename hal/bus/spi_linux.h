#pragma once
// spidev back-end of hal::SpiDevice: /dev/spidevB.C, mode 0, 8-bit words.
// One transfer() is one SPI_IOC_MESSAGE (one chip-select frame); the
// spi_ioc_transfer array lives on the stack (fixed maximum count, no
// allocation). Thin on purpose: it is exercised on the board, the drivers are
// tested against register-level emulators.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <system_error>

#include "hal/bus/spi_device.h"

namespace rilo::hal {

class SpiLinux final : public SpiDevice {
 public:
  /// Most transfers in one message (a DW3000 access needs at most 3:
  /// header, body, CRC).
  static constexpr std::size_t kMaxTransfers = 8;

  /// Opens `path` (e.g. "/dev/spidev0.0") and sets mode 0, 8 bits per word
  /// and `speed_hz`. Throws std::runtime_error naming the path, the step and
  /// strerror(errno) on failure.
  SpiLinux(std::string path, std::uint32_t speed_hz);
  ~SpiLinux() override;
  SpiLinux(const SpiLinux&) = delete;
  SpiLinux& operator=(const SpiLinux&) = delete;

  std::error_code transfer(std::span<const SpiTransfer> transfers) noexcept override;
  std::error_code setSpeedHz(std::uint32_t speed_hz) noexcept override;
  const std::string& path() const noexcept override { return path_; }
  std::uint32_t speedHz() const noexcept { return speed_hz_; }

 private:
  std::string path_;
  int fd_ = -1;
  std::uint32_t speed_hz_ = 0;
};

}  // namespace rilo::hal
