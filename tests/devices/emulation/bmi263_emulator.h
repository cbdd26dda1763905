#pragma once
// Register-level BMI263 emulator behind hal::I2cDevice, on virtual time.
//
// What it models (the parts the driver depends on):
//   - CHIP_ID, soft reset (registers to reset values, the part NACKs for
//     reset_busy_ns, SENSORTIME restarts), FIFO flush;
//   - the configuration load: INIT_CTRL = 0 opens it (only with advanced
//     power save off), INIT_ADDR/INIT_DATA write the blob, INIT_CTRL = 1
//     closes it and init_duration_ns later INTERNAL_STATUS reads init_ok (0x01)
//     if every byte of the expected size was written and the FNV-1a checksum
//     matches, init_err (0x02) otherwise;
//   - PWR_CTRL, ODR (ACC_CONF bits 3:0), ranges; samples only after init_ok
//     with accel and gyro enabled;
//   - SENSORTIME: 24 bit counter on its own oscillator (oscillator_ppm against
//     the virtual clock); samples on multiples of the ODR period in ticks,
//     data from the motion function (true gyro and specific force in SI) plus
//     white noise, quantized for the configured ranges and saturated;
//   - INT1: data-ready pulses (drdy_pulse_ns) or the FIFO watermark level,
//     through INT1_IO_CTRL (output enable, polarity) and INT_MAP_DATA, on an
//     EmulatedInterruptLine (its jitter and failure injection apply);
//   - FIFO in header mode: 0x8C frames (gyro then accel), stream mode (oldest
//     frames dropped when full, reported by a skip frame), a sensortime frame
//     after the last frame, 0x80 when read past the end, a partially read
//     frame re-sent on the next read;
//   - faults: chosen transactions fail with a given error code (NACK,
//     timeout), interrupts can be dropped and samples skipped.
// Every transaction may take virtual time (bus_ns_per_byte) so reads overlap
// the next sample as on a 400 kHz bus.
#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include <Eigen/Core>

#include "devices/emulation/virtual_time.h"
#include "hal/bus/i2c_device.h"

namespace rilo::emu {

struct ImuTruth {
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();   ///< angular rate, sensor frame (rad/s)
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();   ///< specific force, sensor frame (m/s^2)
};
using MotionFunction = std::function<ImuTruth(std::int64_t t_ns)>;

struct Bmi263EmulatorConfig {
  std::string name = "emu:bmi263@0x68";
  std::uint8_t chip_id = 0x24;
  std::size_t expected_blob_bytes = 8192;
  std::uint32_t expected_blob_checksum = 0;  ///< Bmi263Emulator::checksum() of the right blob
  std::int64_t init_duration_ns = 25'000'000;
  std::int64_t reset_busy_ns = 1'000'000;    ///< NACK everything this long after a soft reset
  double oscillator_ppm = 0.0;               ///< +50: SENSORTIME counts 50 ppm fast against virtual time
  std::uint32_t sensortime_at_reset = 0;
  std::int64_t drdy_pulse_ns = 20'000;
  std::int64_t bus_ns_per_byte = 0;          ///< virtual time per byte on the bus (22'500 at 400 kHz)
  std::size_t fifo_capacity_bytes = 2048;
  double accel_noise_m_s2 = 0.0;             ///< white noise per sample (std dev)
  double gyro_noise_rad_s = 0.0;
  double temperature_degc = 31.5;
  /// The part's gyro cross-axis sensitivity: its x output reads
  /// x + gyro_cas / 512 * z; the factor is served as GYR_CAS (feature page
  /// 0, register 0x3C, 7-bit two's complement) as on a BMI270, once the
  /// driver has selected page 0 itself (FEAT_PAGE's reset value is not
  /// trusted: 0x3C reads 0 until then).
  std::int8_t gyro_cas = 0;
  std::uint64_t seed = 1;
};

class Bmi263Emulator final : public hal::I2cDevice {
 public:
  Bmi263Emulator(VirtualClock& clock, EmulatedInterruptLine& int1, MotionFunction motion,
                 Bmi263EmulatorConfig config = {});
  ~Bmi263Emulator() override;
  Bmi263Emulator(const Bmi263Emulator&) = delete;
  Bmi263Emulator& operator=(const Bmi263Emulator&) = delete;

  std::error_code readRegisters(std::uint8_t reg, std::span<std::uint8_t> out) noexcept override;
  std::error_code writeRegisters(std::uint8_t reg, std::span<const std::uint8_t> data) noexcept override;
  const std::string& path() const noexcept override { return config_.name; }

  /// FNV-1a (32 bit): the checksum the emulator verifies the uploaded blob against.
  static std::uint32_t checksum(std::span<const std::uint8_t> bytes);

  // --- fault injection
  /// Transactions number first .. first + count - 1 (0-based over all reads
  /// and writes, see transactionCount()) fail with `error`, without effect.
  void failTransactions(std::uint64_t first, std::uint64_t count, std::error_code error);
  /// The next `count` transactions addressing `reg` fail with `error`.
  void failNextOnRegister(std::uint8_t reg, int count, std::error_code error);
  /// The next `count` samples update the registers and FIFO but raise no interrupt.
  void dropNextInterrupts(int count) { drop_interrupts_ += count; }
  /// The next `count` samples are not produced at all (no data, no frame, no interrupt).
  void skipNextSamples(int count) { skip_samples_ += count; }
  /// The part resets by itself (brown-out): as a soft reset, the driver must bring it up again.
  void brownOut() { softReset(); }

  // --- observation
  std::uint64_t transactionCount() const { return transactions_; }
  std::uint64_t failedTransactions() const { return failed_transactions_; }
  std::uint8_t registerValue(std::uint8_t reg) const { return regs_[reg & 0x7F]; }
  std::uint8_t internalStatus() const { return internal_status_; }
  bool measuring() const;
  std::uint64_t samplesProduced() const { return samples_produced_; }
  std::uint64_t interruptsRaised() const { return interrupts_raised_; }
  std::uint64_t fifoFramesDropped() const { return fifo_frames_dropped_; }
  std::size_t fifoBytes() const;
  std::uint64_t softResets() const { return soft_resets_; }
  std::uint64_t initDataBytesReceived() const { return init_bytes_received_; }
  /// SENSORTIME (unwrapped, from the last reset) at virtual time t_ns.
  std::int64_t ticksAt(std::int64_t t_ns) const;
  /// Virtual time of unwrapped tick `tick` (first ns at which the counter reads it).
  std::int64_t timeOfTick(std::int64_t tick) const;
  /// True time of the sample instant (multiple of the current ODR period) closest to t_ns.
  std::int64_t nearestSampleTimeNs(std::int64_t t_ns) const;
  std::int64_t periodTicks() const;
  const MotionFunction& motion() const { return motion_; }

 private:
  struct RegisterFault {
    int reg;  // -1: by transaction index
    std::uint64_t first;
    std::uint64_t count;
    std::error_code error;
  };

  std::error_code beginTransaction(std::uint8_t reg);
  void busTime(std::size_t bytes);
  void writeByte(std::uint8_t reg, std::uint8_t value);
  std::uint8_t readByte(std::uint8_t reg, std::uint32_t sensortime) const;
  void readFifo(std::span<std::uint8_t> out, std::uint32_t sensortime);
  void softReset();
  void resetRegisters();
  void startInitLoad();
  void finishInitLoad();
  void updateSampling();
  void scheduleSample(std::int64_t tick, std::uint64_t generation);
  void produceSample();
  void pushFifoFrame(const std::array<std::int16_t, 6>& raw);
  void updateInt1();
  std::size_t fifoWatermark() const;
  bool fifoEnabled() const;

  VirtualClock& clock_;
  EmulatedInterruptLine& int1_;
  MotionFunction motion_;
  Bmi263EmulatorConfig config_;
  std::shared_ptr<char> alive_ = std::make_shared<char>(0);  // scheduled events check it

  std::array<std::uint8_t, 128> regs_{};
  std::array<std::uint8_t, 12> data_{};  // acc xyz, gyr xyz
  std::uint8_t status_drdy_ = 0;
  std::uint8_t int_status_1_ = 0;
  std::uint8_t internal_status_ = 0;

  // Configuration load.
  bool load_open_ = false;
  bool feat_page_selected_ = false;  // FEAT_PAGE written since the last reset
  std::vector<std::uint8_t> blob_;
  std::vector<bool> blob_written_;
  bool blob_overrun_ = false;
  std::size_t init_pointer_ = 0;
  std::uint64_t init_bytes_received_ = 0;
  std::uint64_t init_generation_ = 0;

  // Oscillator: tick = sensortime_at_reset + floor((t - epoch) * rate / tick_ns).
  std::int64_t epoch_ns_ = 0;
  long double rate_ = 1.0L;
  std::int64_t busy_until_ns_ = 0;

  // Sampling.
  std::uint64_t sample_generation_ = 0;
  bool sampling_ = false;
  std::int64_t sampling_period_ticks_ = 0;
  std::uint64_t samples_produced_ = 0;
  std::uint64_t interrupts_raised_ = 0;
  int drop_interrupts_ = 0;
  int skip_samples_ = 0;
  bool drdy_pulse_ = false;
  std::uint64_t pulse_id_ = 0;
  std::mt19937_64 rng_;

  // FIFO.
  std::deque<std::array<std::uint8_t, 13>> fifo_;
  std::uint32_t fifo_skipped_pending_ = 0;
  std::uint64_t fifo_frames_dropped_ = 0;

  // Transactions and injected faults.
  std::uint64_t transactions_ = 0;
  std::uint64_t failed_transactions_ = 0;
  std::vector<RegisterFault> faults_;
  std::uint64_t soft_resets_ = 0;
};

}  // namespace rilo::emu
