#pragma once
// The board of a hardware configuration, emulated: a DW3000 (with one
// simulated responder per configured anchor) and a BMI263 at rest, each on
// its own virtual clock (so the two can run in two threads, as rilod, the
// probe and the recorder run them). A blob file the emulator accepts is
// written next to the configuration.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "devices/emulation/bmi263_emulator.h"
#include "devices/emulation/dw3000_emulator.h"
#include "devices/emulation/virtual_time.h"
#include "hal/source.h"
#include "rilod/config.h"
#include "rilod/hardware_sources.h"

namespace rilo::testing {

/// What the emulated sensors see: true distance and clock offset per anchor
/// id (anchors missing here are switched off), and the IMU's motion.
struct BoardTruth {
  struct Responder {
    double distance_m = 5.0;
    double clock_ppm = 0.0;
  };
  std::map<std::uint32_t, Responder> responders;
  Eigen::Vector3d accel_m_s2{0.0, 0.0, 9.80665};  ///< at rest, z up
  Eigen::Vector3d gyro_rad_s{0.01, -0.02, 0.005};
  double accel_noise_m_s2 = 0.02;
  double gyro_noise_rad_s = 0.001;
  std::uint8_t chip_id = 0x24;
  std::uint32_t dev_id = 0xDECA0302;
};

/// The BMI263 configuration blob (random bytes the emulator checks by checksum).
inline std::vector<std::uint8_t> boardBlob() {
  std::mt19937_64 rng(42);
  std::vector<std::uint8_t> blob(8192);
  for (auto& b : blob) b = static_cast<std::uint8_t>(rng() & 0xFF);
  return blob;
}

inline void writeBlob(const std::filesystem::path& file) {
  const std::vector<std::uint8_t> blob = boardBlob();
  std::ofstream out(file, std::ios::binary);
  out.write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
}

/// A hardware configuration (sources.mode: hardware) with four anchors
/// (short addresses 0x0001..0x0004), antenna delays TX 16390 / RX 16380, the
/// blob at `blob.bin` next to the file, and `extra` appended at the end.
inline std::string boardYaml(const std::string& extra = "") {
  return "sources:\n"
         "  mode: hardware\n"
         "  hardware:\n"
         "    uwb:\n"
         "      spi_device: /dev/spidev0.0\n"
         "      irq: {chip: gpiochip0, line: 25}\n"
         "      reset: {chip: gpiochip0, line: 24}\n"
         "      dw3000:\n"
         "        channel: 5\n"
         "        tx_antenna_delay: 16390\n"
         "        rx_antenna_delay: 16380\n"
         "        anchors:\n"
         "          - {id: 0, short_address: 0x0001}\n"
         "          - {id: 1, short_address: 0x0002}\n"
         "          - {id: 2, short_address: 0x0003}\n"
         "          - {id: 3, short_address: 0x0004}\n"
         "    imu:\n"
         "      i2c_device: /dev/i2c-1\n"
         "      irq: {chip: gpiochip0, line: 23}\n"
         "      bmi263:\n"
         "        config_blob_path: blob.bin\n"
         "        odr_hz: 800\n"
         "anchors:\n"
         "  - {id: 0, x: 0, y: 0, z: 2.5}\n"
         "  - {id: 1, x: 6, y: 0, z: 1.0}\n"
         "  - {id: 2, x: 6, y: 5, z: 2.5}\n"
         "  - {id: 3, x: 0, y: 5, z: 1.0}\n" +
         extra;
}

class EmulatedBoard {
 public:
  EmulatedBoard(const HardwareSourceConfig& config, const BoardTruth& truth) {
    const dw3000::Dw3000Config& uwb = config.uwb.dw3000;
    emu::Dw3000EmulatorParams params;
    params.dev_id = truth.dev_id;
    // Physical delays equal to the configured ones: ranges are unbiased.
    params.true_tx_antenna_delay_units = uwb.tx_antenna_delay;
    params.true_rx_antenna_delay_units = uwb.rx_antenna_delay;
    dw3000_ = std::make_unique<emu::Dw3000Emulator>(uwb_clock_, uwb_irq_, &uwb_reset_, params);
    for (const dw3000::AnchorConfig& a : uwb.anchors) {
      emu::Dw3000ResponderModel model;
      model.short_address = a.short_address;
      model.pan_id = uwb.pan_id;
      model.channel = static_cast<int>(uwb.channel);
      model.preamble_code = uwb.preamble_code;
      model.reply_delay_us = uwb.reply_delay_us;
      const auto it = truth.responders.find(a.id);
      model.present = it != truth.responders.end();
      if (model.present) {
        const double d = it->second.distance_m;
        model.distance_m = [d](std::int64_t) { return d; };
        model.clock_ppm = it->second.clock_ppm;
      }
      dw3000_->addResponder(std::move(model));
    }

    emu::Bmi263EmulatorConfig imu;
    imu.chip_id = truth.chip_id;
    imu.expected_blob_checksum = emu::Bmi263Emulator::checksum(boardBlob());
    imu.accel_noise_m_s2 = truth.accel_noise_m_s2;
    imu.gyro_noise_rad_s = truth.gyro_noise_rad_s;
    const Eigen::Vector3d accel = truth.accel_m_s2;
    const Eigen::Vector3d gyro = truth.gyro_rad_s;
    bmi263_ = std::make_unique<emu::Bmi263Emulator>(
        imu_clock_, imu_irq_,
        [accel, gyro](std::int64_t) {
          emu::ImuTruth t;
          t.accel_m_s2 = accel;
          t.gyro_rad_s = gyro;
          return t;
        },
        imu);
  }

  UwbBuses uwb() { return UwbBuses{dw3000_.get(), &uwb_irq_, &uwb_reset_, &uwb_clock_}; }
  ImuBuses imu() { return ImuBuses{bmi263_.get(), &imu_irq_, &imu_clock_}; }
  emu::Dw3000Emulator& dw3000() { return *dw3000_; }
  emu::Bmi263Emulator& bmi263() { return *bmi263_; }
  emu::VirtualClock& uwbClock() { return uwb_clock_; }
  emu::VirtualClock& imuClock() { return imu_clock_; }

 private:
  emu::VirtualClock uwb_clock_{1'000'000'000};
  emu::EmulatedInterruptLine uwb_irq_{uwb_clock_, "emu:gpiochip0:25"};
  emu::EmulatedOutputLine uwb_reset_{"emu:gpiochip0:24"};
  std::unique_ptr<emu::Dw3000Emulator> dw3000_;
  emu::VirtualClock imu_clock_{1'000'000'000};
  emu::EmulatedInterruptLine imu_irq_{imu_clock_, "emu:gpiochip0:23"};
  std::unique_ptr<emu::Bmi263Emulator> bmi263_;
};

/// Runs `inner` until its (virtual) clock passes `duration_ns` after the
/// start, checked on every sample and fault, or until the outer stop.
class TimeLimitedSource final : public SampleSource {
 public:
  TimeLimitedSource(std::unique_ptr<SampleSource> inner, hal::Clock& clock, std::int64_t duration_ns)
      : inner_(std::move(inner)), clock_(clock), duration_ns_(duration_ns) {}

  SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override {
    Limit limit(sink, clock_, clock_.nowNs() + duration_ns_, stop);
    return inner_->run(limit, limit.stop);
  }
  std::string describe() const override { return inner_->describe(); }

 private:
  struct Limit final : SampleSink {
    Limit(SampleSink& out_sink, hal::Clock& c, std::int64_t end, const std::atomic<bool>& outer)
        : out(out_sink), clock(c), end_ns(end), outer_stop(outer) {}
    void push(const Sample& s) noexcept override {
      out.push(s);
      check();
    }
    void fault(const SourceFault& f) noexcept override {
      out.fault(f);
      check();
    }
    void note(const SourceNote& n) noexcept override { out.note(n); }
    void idle() noexcept override { out.idle(); }
    void check() noexcept {
      if (clock.nowNs() >= end_ns || outer_stop.load()) stop.store(true);
    }
    SampleSink& out;
    hal::Clock& clock;
    std::int64_t end_ns;
    const std::atomic<bool>& outer_stop;
    std::atomic<bool> stop{false};
  };

  std::unique_ptr<SampleSource> inner_;
  hal::Clock& clock_;
  std::int64_t duration_ns_;
};

}  // namespace rilo::testing
