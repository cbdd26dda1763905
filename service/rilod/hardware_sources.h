#pragma once
// The board's devices from the configuration's sources.hardware section, in
// one place for rilod, `rilo probe` and `rilo record`: open the Linux
// back-ends (spidev, i2c-dev, libgpiod lines), and build the DWM3000 and
// BMI263 sources on any implementation of the bus interfaces (the Linux
// back-ends on the board, the register-level emulators in tests).
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "hal/bus/clock.h"
#include "hal/bus/gpio_line.h"
#include "hal/bus/gpio_linux.h"
#include "hal/bus/i2c_device.h"
#include "hal/bus/i2c_linux.h"
#include "hal/bus/spi_device.h"
#include "hal/bus/spi_linux.h"
#include "hal/source.h"
#include "rilod/config.h"

namespace rilo {

/// A device node or GPIO line could not be opened. what() names the
/// configuration key, the device path and the system's reason.
class HardwareOpenError : public std::runtime_error {
 public:
  HardwareOpenError(std::string device, const std::string& message)
      : std::runtime_error(message), device_(std::move(device)) {}
  /// "/dev/spidev0.0", "gpiochip0:25", "/dev/i2c-1@0x68".
  const std::string& device() const noexcept { return device_; }

 private:
  std::string device_;
};

/// The DWM3000's buses as its driver sees them (borrowed; reset may be null).
struct UwbBuses {
  hal::SpiDevice* spi = nullptr;
  hal::InterruptLine* irq = nullptr;
  hal::OutputLine* reset = nullptr;
  hal::Clock* clock = nullptr;
};

/// The BMI263's buses as its driver sees them (borrowed).
struct ImuBuses {
  hal::I2cDevice* i2c = nullptr;
  hal::InterruptLine* irq = nullptr;
  hal::Clock* clock = nullptr;
};

/// The Linux back-ends of both devices and the one clock (CLOCK_MONOTONIC).
/// Members stay null until opened; keep this alive while a source uses them.
struct LinuxHardware {
  hal::MonotonicClock clock;
  std::unique_ptr<hal::SpiLinux> uwb_spi;
  std::unique_ptr<hal::GpioInterruptLine> uwb_irq;
  std::unique_ptr<hal::GpioOutputLine> uwb_reset;
  std::unique_ptr<hal::I2cLinux> imu_i2c;
  std::unique_ptr<hal::GpioInterruptLine> imu_irq;

  /// Opens the DWM3000's spidev node (at the slow SPI clock), its IRQ line
  /// and, if configured, its reset line (driven high). `consumer` labels the
  /// GPIO lines ("rilod-uwb"). Throws HardwareOpenError.
  void openUwb(const UwbHardwareConfig& config, const std::string& consumer);
  /// Opens the BMI263's i2c-dev node and INT1 line. Throws HardwareOpenError.
  void openImu(const ImuHardwareConfig& config, const std::string& consumer);
  /// Both, DWM3000 first. `consumer` is suffixed "-uwb" / "-imu".
  void openAll(const HardwareSourceConfig& config, const std::string& consumer);

  /// Views of what is open (openUwb / openImu must have succeeded).
  UwbBuses uwb();
  ImuBuses imu();
};

/// The sources.hardware section of a loaded configuration. Throws
/// std::invalid_argument naming the file when sources.mode is not hardware
/// (the tools only run the devices rilod would run).
const HardwareSourceConfig& requireHardwareSection(const ServiceConfig& config);

/// The DWM3000 SS-TWR source (Dw3000Source) on `buses`.
/// Throws std::invalid_argument for a bad configuration or missing bus.
std::unique_ptr<SampleSource> makeUwbSource(const UwbHardwareConfig& config, const UwbBuses& buses);
/// The BMI263 source (Bmi263Source) on `buses`. Throws std::invalid_argument.
std::unique_ptr<SampleSource> makeImuSource(const ImuHardwareConfig& config, const ImuBuses& buses);
/// Both, in rilod's order: index 0 the DWM3000 (thread role "source 0" gets
/// the uwb real-time settings), index 1 the BMI263.
std::vector<std::unique_ptr<SampleSource>> makeHardwareSources(const HardwareSourceConfig& config,
                                                               const UwbBuses& uwb, const ImuBuses& imu);

}  // namespace rilo
