#include "rilod/hardware_sources.h"

#include <cstdio>
#include <exception>

#include "hal/bmi263/bmi263_source.h"
#include "hal/dw3000/dw3000_source.h"

namespace rilo {
namespace {

std::string lineName(const GpioLineConfig& line) { return line.chip + ":" + std::to_string(line.line); }

std::string i2cName(const ImuHardwareConfig& config) {
  char address[8];
  std::snprintf(address, sizeof address, "0x%02X", static_cast<unsigned>(config.i2c_address));
  return config.i2c_device + "@" + address;
}

/// Runs `open`; any exception becomes a HardwareOpenError naming the key and device.
template <typename Open>
void opening(const std::string& key, const std::string& device, Open&& open) {
  try {
    open();
  } catch (const std::exception& e) {
    throw HardwareOpenError(device, "cannot open " + device + " (" + key + "): " + e.what());
  }
}

}  // namespace

void LinuxHardware::openUwb(const UwbHardwareConfig& config, const std::string& consumer) {
  opening("sources.hardware.uwb.spi_device", config.spi_device,
          [&] { uwb_spi = std::make_unique<hal::SpiLinux>(config.spi_device, config.dw3000.spi_slow_hz); });
  opening("sources.hardware.uwb.irq", lineName(config.irq),
          [&] { uwb_irq = std::make_unique<hal::GpioInterruptLine>(config.irq.chip, config.irq.line, consumer); });
  if (config.reset) {
    opening("sources.hardware.uwb.reset", lineName(*config.reset), [&] {
      uwb_reset = std::make_unique<hal::GpioOutputLine>(config.reset->chip, config.reset->line, true, consumer);
    });
  }
}

void LinuxHardware::openImu(const ImuHardwareConfig& config, const std::string& consumer) {
  opening("sources.hardware.imu.i2c_device", i2cName(config),
          [&] { imu_i2c = std::make_unique<hal::I2cLinux>(config.i2c_device, config.i2c_address); });
  opening("sources.hardware.imu.irq", lineName(config.irq),
          [&] { imu_irq = std::make_unique<hal::GpioInterruptLine>(config.irq.chip, config.irq.line, consumer); });
}

void LinuxHardware::openAll(const HardwareSourceConfig& config, const std::string& consumer) {
  openUwb(config.uwb, consumer + "-uwb");
  openImu(config.imu, consumer + "-imu");
}

UwbBuses LinuxHardware::uwb() { return UwbBuses{uwb_spi.get(), uwb_irq.get(), uwb_reset.get(), &clock}; }

ImuBuses LinuxHardware::imu() { return ImuBuses{imu_i2c.get(), imu_irq.get(), &clock}; }

const HardwareSourceConfig& requireHardwareSection(const ServiceConfig& config) {
  if (config.sources.mode != SourceMode::kHardware) {
    throw std::invalid_argument(config.file.string() + ": sources.mode is " + std::string(toString(config.sources.mode)) +
                                "; the hardware tools need `sources: {mode: hardware, hardware: ...}` "
                                "(see config/rilod-hardware.yaml)");
  }
  return config.sources.hardware;
}

std::unique_ptr<SampleSource> makeUwbSource(const UwbHardwareConfig& config, const UwbBuses& buses) {
  if (buses.spi == nullptr || buses.irq == nullptr || buses.clock == nullptr) {
    throw std::invalid_argument("makeUwbSource: buses: the SPI device, IRQ line and clock are required");
  }
  return std::make_unique<dw3000::Dw3000Source>(config.dw3000, *buses.spi, *buses.irq, buses.reset, *buses.clock);
}

std::unique_ptr<SampleSource> makeImuSource(const ImuHardwareConfig& config, const ImuBuses& buses) {
  if (buses.i2c == nullptr || buses.irq == nullptr || buses.clock == nullptr) {
    throw std::invalid_argument("makeImuSource: buses: the I2C device, IRQ line and clock are required");
  }
  return std::make_unique<bmi263::Bmi263Source>(*buses.i2c, *buses.irq, *buses.clock, config.bmi263);
}

std::vector<std::unique_ptr<SampleSource>> makeHardwareSources(const HardwareSourceConfig& config,
                                                               const UwbBuses& uwb, const ImuBuses& imu) {
  std::vector<std::unique_ptr<SampleSource>> sources;
  sources.push_back(makeUwbSource(config.uwb, uwb));
  sources.push_back(makeImuSource(config.imu, imu));
  return sources;
}

}  // namespace rilo
