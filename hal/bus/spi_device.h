#pragma once
// SPI bus seen by a device driver: one call = one chip-select frame made of
// several full-duplex transfers (as spidev's SPI_IOC_MESSAGE). Implemented by
// the spidev back-end on the board and by register-level emulators in tests.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <system_error>

namespace rilo::hal {

struct SpiTransfer {
  const std::uint8_t* tx = nullptr;  ///< bytes clocked out (nullptr: zeros)
  std::uint8_t* rx = nullptr;        ///< bytes clocked in (nullptr: discarded)
  std::size_t len = 0;
  /// Deselect the chip after this transfer (spidev cs_change); normally the
  /// chip stays selected for the whole message.
  bool cs_change = false;
};

class SpiDevice {
 public:
  virtual ~SpiDevice() = default;
  /// One message: the transfers in order under one chip select. Returns an
  /// errno-style error on failure (no allocation, no throw: fault paths are
  /// counted by the driver, which builds the message with path()).
  virtual std::error_code transfer(std::span<const SpiTransfer> transfers) noexcept = 0;
  /// Clock for the following messages (slow during reset, fast afterwards).
  virtual std::error_code setSpeedHz(std::uint32_t speed_hz) noexcept = 0;
  /// Device node or emulator name, for error messages ("/dev/spidev0.0").
  virtual const std::string& path() const noexcept = 0;
};

}  // namespace rilo::hal
