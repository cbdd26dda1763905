#include "devices/emulation/bmi263_emulator.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "hal/bmi263/bmi263_registers.h"

namespace rilo::emu {

namespace b = rilo::bmi263;

namespace {

std::int16_t quantize(double value, double lsb_per_unit) {
  const double raw = std::round(value * lsb_per_unit);
  return static_cast<std::int16_t>(std::clamp(raw, -32768.0, 32767.0));
}

void putLe16(std::uint8_t* p, std::int16_t v) {
  const auto u = static_cast<std::uint16_t>(v);
  p[0] = static_cast<std::uint8_t>(u & 0xFF);
  p[1] = static_cast<std::uint8_t>(u >> 8);
}

}  // namespace

Bmi263Emulator::Bmi263Emulator(VirtualClock& clock, EmulatedInterruptLine& int1, MotionFunction motion,
                               Bmi263EmulatorConfig config)
    : clock_(clock), int1_(int1), motion_(std::move(motion)), config_(std::move(config)), rng_(config_.seed) {
  rate_ = 1.0L + static_cast<long double>(config_.oscillator_ppm) * 1e-6L;
  epoch_ns_ = clock_.nowNs();
  resetRegisters();
  updateInt1();
}

Bmi263Emulator::~Bmi263Emulator() = default;

std::uint32_t Bmi263Emulator::checksum(std::span<const std::uint8_t> bytes) {
  std::uint32_t hash = 2166136261u;
  for (const std::uint8_t byte : bytes) {
    hash ^= byte;
    hash *= 16777619u;
  }
  return hash;
}

void Bmi263Emulator::failTransactions(std::uint64_t first, std::uint64_t count, std::error_code error) {
  faults_.push_back({-1, first, count, error});
}

void Bmi263Emulator::failNextOnRegister(std::uint8_t reg, int count, std::error_code error) {
  faults_.push_back({reg, 0, static_cast<std::uint64_t>(count), error});
}

// ---------------------------------------------------------------------------
// Oscillator

std::int64_t Bmi263Emulator::ticksAt(std::int64_t t_ns) const {
  const long double elapsed = static_cast<long double>(t_ns - epoch_ns_);
  const auto ticks = static_cast<std::int64_t>(std::floor(elapsed * rate_ / static_cast<long double>(b::kSensorTimeTickNs)));
  return static_cast<std::int64_t>(config_.sensortime_at_reset) + ticks;
}

std::int64_t Bmi263Emulator::timeOfTick(std::int64_t tick) const {
  const long double ticks = static_cast<long double>(tick - static_cast<std::int64_t>(config_.sensortime_at_reset));
  auto t_ns = epoch_ns_ + static_cast<std::int64_t>(
                              std::ceil(ticks * static_cast<long double>(b::kSensorTimeTickNs) / rate_));
  while (ticksAt(t_ns) < tick) ++t_ns;
  while (ticksAt(t_ns - 1) >= tick) --t_ns;
  return t_ns;
}

std::int64_t Bmi263Emulator::periodTicks() const {
  return b::odr::periodTicks(regs_[b::reg::kAccConf] & b::bits::kConfOdrMask);
}

std::int64_t Bmi263Emulator::nearestSampleTimeNs(std::int64_t t_ns) const {
  const std::int64_t p = periodTicks();
  if (p <= 0) return t_ns;
  const std::int64_t k = ticksAt(t_ns) / p;
  std::int64_t best = timeOfTick(k * p);
  for (const std::int64_t candidate : {k - 1, k + 1}) {
    const std::int64_t t = timeOfTick(candidate * p);
    if (std::llabs(t - t_ns) < std::llabs(best - t_ns)) best = t;
  }
  return best;
}

// ---------------------------------------------------------------------------
// Registers

void Bmi263Emulator::resetRegisters() {
  regs_.fill(0);
  regs_[b::reg::kChipId] = config_.chip_id;
  regs_[b::reg::kAccConf] = 0xA8;
  regs_[b::reg::kAccRange] = 0x02;
  regs_[b::reg::kGyrConf] = 0xA9;
  regs_[b::reg::kGyrRange] = 0x00;
  regs_[b::reg::kFifoDowns] = 0x88;
  regs_[b::reg::kFifoConfig0] = 0x02;
  regs_[b::reg::kFifoConfig1] = 0x10;
  regs_[b::reg::kPwrConf] = 0x03;
  regs_[b::reg::kPwrCtrl] = 0x00;
  data_.fill(0);
  status_drdy_ = 0;
  int_status_1_ = 0;
  internal_status_ = b::internal_status::kNotInit;
  load_open_ = false;
  blob_.clear();
  blob_written_.clear();
  init_pointer_ = 0;
  ++init_generation_;
  fifo_.clear();
  fifo_skipped_pending_ = 0;
  drdy_pulse_ = false;
}

void Bmi263Emulator::softReset() {
  ++soft_resets_;
  feat_page_selected_ = false;
  resetRegisters();
  epoch_ns_ = clock_.nowNs();
  busy_until_ns_ = clock_.nowNs() + config_.reset_busy_ns;
  updateSampling();
  updateInt1();
}

bool Bmi263Emulator::measuring() const {
  const std::uint8_t both = b::bits::kPwrCtrlAcc | b::bits::kPwrCtrlGyr;
  return internal_status_ == b::internal_status::kInitOk && (regs_[b::reg::kPwrCtrl] & both) == both &&
         periodTicks() > 0;
}

bool Bmi263Emulator::fifoEnabled() const {
  const std::uint8_t need = b::bits::kFifoConfig1HeaderEn | b::bits::kFifoConfig1AccEn | b::bits::kFifoConfig1GyrEn;
  return (regs_[b::reg::kFifoConfig1] & need) == need;
}

std::size_t Bmi263Emulator::fifoWatermark() const {
  return static_cast<std::size_t>(regs_[b::reg::kFifoWtm0]) |
         (static_cast<std::size_t>(regs_[b::reg::kFifoWtm0 + 1] & 0x1F) << 8);
}

std::size_t Bmi263Emulator::fifoBytes() const {
  return fifo_.size() * b::fifo::kAccGyrFrameBytes + (fifo_skipped_pending_ > 0 ? 2 : 0);
}

std::error_code Bmi263Emulator::beginTransaction(std::uint8_t reg) {
  const std::uint64_t index = transactions_++;
  for (RegisterFault& fault : faults_) {
    if (fault.count == 0) continue;
    if (fault.reg < 0) {
      if (index >= fault.first && index < fault.first + fault.count) {
        ++failed_transactions_;
        busTime(1);
        return fault.error;
      }
    } else if (fault.reg == reg) {
      --fault.count;
      ++failed_transactions_;
      busTime(1);
      return fault.error;
    }
  }
  if (clock_.nowNs() < busy_until_ns_) {
    ++failed_transactions_;
    busTime(1);
    return std::make_error_code(std::errc::no_such_device_or_address);  // address NACK
  }
  return {};
}

void Bmi263Emulator::busTime(std::size_t bytes) {
  if (config_.bus_ns_per_byte <= 0) return;
  // Address byte plus payload; device events (samples) keep running meanwhile.
  clock_.advanceTo(clock_.nowNs() + static_cast<std::int64_t>(bytes + 1) * config_.bus_ns_per_byte);
}

std::uint8_t Bmi263Emulator::readByte(std::uint8_t reg, std::uint32_t sensortime) const {
  switch (reg) {
    case b::reg::kStatus: return static_cast<std::uint8_t>(b::bits::kStatusCmdRdy | status_drdy_);
    case b::reg::kSensorTime0: return static_cast<std::uint8_t>(sensortime & 0xFF);
    case b::reg::kSensorTime0 + 1: return static_cast<std::uint8_t>((sensortime >> 8) & 0xFF);
    case b::reg::kSensorTime0 + 2: return static_cast<std::uint8_t>((sensortime >> 16) & 0xFF);
    case b::reg::kIntStatus1: return int_status_1_;
    case b::reg::kInternalStatus: return internal_status_;
    case b::reg::kTemperature0:
    case b::reg::kTemperature0 + 1: {
      std::uint16_t raw = 0x8000;
      if ((regs_[b::reg::kPwrCtrl] & b::bits::kPwrCtrlTemp) != 0) {
        raw = static_cast<std::uint16_t>(quantize(config_.temperature_degc - 23.0, 512.0));
      }
      return reg == b::reg::kTemperature0 ? static_cast<std::uint8_t>(raw & 0xFF)
                                          : static_cast<std::uint8_t>(raw >> 8);
    }
    case b::reg::kFifoLength0: return static_cast<std::uint8_t>(fifoBytes() & 0xFF);
    case b::reg::kFifoLength0 + 1: return static_cast<std::uint8_t>((fifoBytes() >> 8) & 0x3F);
    case b::reg::kFifoData: return b::fifo::kHeaderEmpty;
    case b::reg::kGyrCas:
      return feat_page_selected_ && regs_[b::reg::kFeatPage] == 0 ? static_cast<std::uint8_t>(config_.gyro_cas & 0x7F)
                                                                  : std::uint8_t{0};
    default: break;
  }
  if (reg >= b::reg::kAccDataX && reg < b::reg::kAccDataX + 12) return data_[reg - b::reg::kAccDataX];
  return reg < 0x80 ? regs_[reg] : 0;
}

std::error_code Bmi263Emulator::readRegisters(std::uint8_t reg, std::span<std::uint8_t> out) noexcept {
  if (const std::error_code error = beginTransaction(reg)) return error;
  // The burst is consistent: everything is taken at the start of the read
  // (SENSORTIME latched with the data, as the part shadows a burst).
  const auto sensortime = static_cast<std::uint32_t>(ticksAt(clock_.nowNs()) & b::kSensorTimeMask);
  if (reg == b::reg::kFifoData) {
    readFifo(out, sensortime);
  } else {
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = readByte(static_cast<std::uint8_t>(reg + i), sensortime);
    const std::size_t end = reg + out.size();
    if (reg < b::reg::kAccDataX + 6 && end > b::reg::kAccDataX) status_drdy_ &= ~b::bits::kStatusDrdyAcc;
    if (reg < b::reg::kGyrDataX + 6 && end > b::reg::kGyrDataX) status_drdy_ &= ~b::bits::kStatusDrdyGyr;
    if (reg <= b::reg::kIntStatus1 && end > b::reg::kIntStatus1) int_status_1_ = 0;
  }
  busTime(1 + out.size());
  return {};
}

void Bmi263Emulator::readFifo(std::span<std::uint8_t> out, std::uint32_t sensortime) {
  std::size_t i = 0;
  // Skip frame first (frames were dropped before the ones still stored).
  if (fifo_skipped_pending_ > 0) {
    if (out.size() - i < 2) {
      std::fill(out.begin() + static_cast<std::ptrdiff_t>(i), out.end(), std::uint8_t{b::fifo::kHeaderSkip});
      return;
    }
    out[i++] = b::fifo::kHeaderSkip;
    out[i++] = static_cast<std::uint8_t>(std::min<std::uint32_t>(fifo_skipped_pending_, 255));
    fifo_skipped_pending_ = 0;
  }
  while (!fifo_.empty()) {
    const auto& frame = fifo_.front();
    const std::size_t room = out.size() - i;
    if (room < frame.size()) {
      // Partially read: the bytes go out, the frame stays for the next read.
      std::copy_n(frame.begin(), room, out.begin() + static_cast<std::ptrdiff_t>(i));
      updateInt1();
      return;
    }
    std::copy(frame.begin(), frame.end(), out.begin() + static_cast<std::ptrdiff_t>(i));
    i += frame.size();
    fifo_.pop_front();
  }
  // Drained: the sensortime frame, then "empty" headers.
  if ((regs_[b::reg::kFifoConfig0] & b::bits::kFifoConfig0TimeEn) != 0) {
    const std::uint8_t time_frame[4] = {b::fifo::kHeaderSensorTime, static_cast<std::uint8_t>(sensortime & 0xFF),
                                        static_cast<std::uint8_t>((sensortime >> 8) & 0xFF),
                                        static_cast<std::uint8_t>((sensortime >> 16) & 0xFF)};
    for (std::size_t k = 0; k < 4 && i < out.size(); ++k) out[i++] = time_frame[k];
  }
  while (i < out.size()) out[i++] = b::fifo::kHeaderEmpty;
  updateInt1();
}

std::error_code Bmi263Emulator::writeRegisters(std::uint8_t reg, std::span<const std::uint8_t> data) noexcept {
  if (const std::error_code error = beginTransaction(reg)) return error;
  if (reg == b::reg::kInitData) {
    // Write port: every byte goes to the configuration buffer.
    for (const std::uint8_t byte : data) {
      ++init_bytes_received_;
      if (!load_open_) continue;
      if (init_pointer_ < blob_.size()) {
        blob_[init_pointer_] = byte;
        blob_written_[init_pointer_] = true;
      } else {
        blob_overrun_ = true;
      }
      ++init_pointer_;
    }
  } else {
    for (std::size_t i = 0; i < data.size(); ++i) writeByte(static_cast<std::uint8_t>(reg + i), data[i]);
  }
  busTime(1 + data.size());
  return {};
}

void Bmi263Emulator::writeByte(std::uint8_t reg, std::uint8_t value) {
  if (reg >= 0x80) return;
  if (reg == b::reg::kFeatPage) feat_page_selected_ = true;
  switch (reg) {
    case b::reg::kCmd:
      if (value == b::cmd::kSoftReset) {
        softReset();
      } else if (value == b::cmd::kFifoFlush) {
        fifo_.clear();
        fifo_skipped_pending_ = 0;
        updateInt1();
      }
      return;
    case b::reg::kInitCtrl:
      regs_[reg] = value;
      if (value == 0x00) {
        startInitLoad();
      } else if (value == 0x01) {
        finishInitLoad();
      }
      return;
    case b::reg::kInitAddr0:
    case b::reg::kInitAddr1:
      regs_[reg] = value;
      init_pointer_ = ((static_cast<std::size_t>(regs_[b::reg::kInitAddr0]) & 0x0F) |
                       (static_cast<std::size_t>(regs_[b::reg::kInitAddr1]) << 4)) * 2;
      return;
    case b::reg::kPwrCtrl:
    case b::reg::kAccConf:
    case b::reg::kGyrConf:
      regs_[reg] = value;
      updateSampling();
      return;
    case b::reg::kFifoWtm0:
    case b::reg::kFifoWtm0 + 1:
    case b::reg::kFifoConfig0:
    case b::reg::kFifoConfig1:
    case b::reg::kInt1IoCtrl:
    case b::reg::kIntLatch:
    case b::reg::kIntMapData:
      regs_[reg] = value;
      updateInt1();
      return;
    default: break;
  }
  if (reg < b::reg::kAccConf) return;  // 0x00..0x3F: read-only status and data
  regs_[reg] = value;
}

// ---------------------------------------------------------------------------
// Configuration load

void Bmi263Emulator::startInitLoad() {
  ++init_generation_;
  internal_status_ = b::internal_status::kNotInit;
  updateSampling();
  // With advanced power save on, the part cannot take burst writes: the load
  // silently does not happen (and ends in init_err).
  load_open_ = (regs_[b::reg::kPwrConf] & b::bits::kPwrConfAdvPowerSave) == 0;
  blob_.assign(config_.expected_blob_bytes, 0);
  blob_written_.assign(config_.expected_blob_bytes, false);
  blob_overrun_ = false;
}

void Bmi263Emulator::finishInitLoad() {
  const bool complete = load_open_ && !blob_overrun_ &&
                        std::all_of(blob_written_.begin(), blob_written_.end(), [](bool w) { return w; });
  const bool ok = complete && checksum(blob_) == config_.expected_blob_checksum;
  load_open_ = false;
  const std::uint64_t generation = ++init_generation_;
  std::weak_ptr<char> alive = alive_;
  clock_.schedule(clock_.nowNs() + config_.init_duration_ns, [this, alive, generation, ok] {
    if (alive.expired() || generation != init_generation_) return;
    internal_status_ = ok ? b::internal_status::kInitOk : b::internal_status::kInitErr;
    updateSampling();
  });
}

// ---------------------------------------------------------------------------
// Sampling

void Bmi263Emulator::updateSampling() {
  const bool on = measuring();
  const std::int64_t p = periodTicks();
  if (on == sampling_ && (!on || p == sampling_period_ticks_)) return;
  const std::uint64_t generation = ++sample_generation_;  // cancels the scheduled sample
  sampling_ = on;
  sampling_period_ticks_ = p;
  if (!on) return;
  const std::int64_t next = (ticksAt(clock_.nowNs()) / p + 1) * p;
  scheduleSample(next, generation);
}

void Bmi263Emulator::scheduleSample(std::int64_t tick, std::uint64_t generation) {
  std::weak_ptr<char> alive = alive_;
  clock_.schedule(timeOfTick(tick), [this, alive, tick, generation] {
    if (alive.expired() || generation != sample_generation_) return;
    produceSample();
    scheduleSample(tick + sampling_period_ticks_, generation);
  });
}

void Bmi263Emulator::produceSample() {
  if (skip_samples_ > 0) {
    --skip_samples_;
    return;
  }
  ++samples_produced_;
  ImuTruth truth = motion_ ? motion_(clock_.nowNs()) : ImuTruth{};
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int axis = 0; axis < 3; ++axis) {
    if (config_.accel_noise_m_s2 > 0.0) truth.accel_m_s2[axis] += config_.accel_noise_m_s2 * normal(rng_);
    if (config_.gyro_noise_rad_s > 0.0) truth.gyro_rad_s[axis] += config_.gyro_noise_rad_s * normal(rng_);
  }
  const double accel_lsb_per_m_s2 = 32768.0 / (2.0 * static_cast<double>(1 << (regs_[b::reg::kAccRange] & 0x03))) /
                                    b::kStandardGravity;
  const int gyro_code = std::min(regs_[b::reg::kGyrRange] & 0x07, 4);
  const double gyro_lsb_per_rad_s = 32768.0 / (2000.0 / static_cast<double>(1 << gyro_code)) *
                                    (180.0 / std::numbers::pi);
  truth.gyro_rad_s[0] += static_cast<double>(config_.gyro_cas) / 512.0 * truth.gyro_rad_s[2];  // cross-axis
  std::array<std::int16_t, 6> raw{};  // acc xyz, gyr xyz
  for (std::size_t axis = 0; axis < 3; ++axis) {
    raw[axis] = quantize(truth.accel_m_s2[static_cast<Eigen::Index>(axis)], accel_lsb_per_m_s2);
    raw[3 + axis] = quantize(truth.gyro_rad_s[static_cast<Eigen::Index>(axis)], gyro_lsb_per_rad_s);
  }
  for (std::size_t k = 0; k < 6; ++k) putLe16(data_.data() + 2 * k, raw[k]);
  status_drdy_ |= b::bits::kStatusDrdyAcc | b::bits::kStatusDrdyGyr;
  int_status_1_ |= b::bits::kIntStatus1AccDrdy | b::bits::kIntStatus1GyrDrdy;
  if (fifoEnabled()) pushFifoFrame(raw);

  if (drop_interrupts_ > 0) {
    --drop_interrupts_;
    updateInt1();
    return;
  }
  if ((regs_[b::reg::kIntMapData] & b::bits::kIntMapDrdyInt1) != 0) {
    drdy_pulse_ = true;
    const std::uint64_t id = ++pulse_id_;
    updateInt1();
    std::weak_ptr<char> alive = alive_;
    clock_.schedule(clock_.nowNs() + config_.drdy_pulse_ns, [this, alive, id] {
      if (alive.expired() || id != pulse_id_) return;
      drdy_pulse_ = false;
      updateInt1();
    });
  } else {
    updateInt1();
  }
}

void Bmi263Emulator::pushFifoFrame(const std::array<std::int16_t, 6>& raw) {
  std::array<std::uint8_t, 13> frame{};
  frame[0] = b::fifo::kHeaderAccGyr;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    putLe16(frame.data() + 1 + 2 * axis, raw[3 + axis]);  // gyro first
    putLe16(frame.data() + 7 + 2 * axis, raw[axis]);
  }
  fifo_.push_back(frame);
  // Stream mode: drop the oldest frames when full, report them in a skip frame.
  while (fifoBytes() > config_.fifo_capacity_bytes && !fifo_.empty()) {
    fifo_.pop_front();
    ++fifo_skipped_pending_;
    ++fifo_frames_dropped_;
  }
}

void Bmi263Emulator::updateInt1() {
  const std::uint8_t map = regs_[b::reg::kIntMapData];
  bool asserted = false;
  if ((map & b::bits::kIntMapDrdyInt1) != 0) asserted = asserted || drdy_pulse_;
  const std::size_t watermark = fifoWatermark();
  if ((map & b::bits::kIntMapFwmInt1) != 0 && watermark > 0) asserted = asserted || fifoBytes() >= watermark;
  if ((map & b::bits::kIntMapFfullInt1) != 0) {
    asserted = asserted || fifoBytes() + b::fifo::kAccGyrFrameBytes > config_.fifo_capacity_bytes;
  }
  const std::uint8_t io = regs_[b::reg::kInt1IoCtrl];
  bool level = false;  // output disabled: pulled low
  if ((io & b::bits::kInt1OutputEn) != 0) level = ((io & b::bits::kInt1ActiveHigh) != 0) == asserted;
  if (level && !int1_.level()) ++interrupts_raised_;
  int1_.setLevel(level);
}

}  // namespace rilo::emu
