#include "rilod/hardware_probe.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <exception>
#include <memory>
#include <stdexcept>
#include <thread>
#include <utility>
#include <variant>

#include <nlohmann/json.hpp>

#include "hal/bmi263/bmi263_driver.h"
#include "hal/bmi263/bmi263_registers.h"
#include "hal/bmi263/bmi263_source.h"
#include "hal/dw3000/dw3000_device.h"
#include "hal/dw3000/registers.h"

namespace rilo {
namespace {

constexpr std::size_t kMaxFaultMessages = 8;

std::int64_t secondsToNs(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

const char* dataRateName(dw3000::DataRate rate) { return rate == dw3000::DataRate::k6M8 ? "6.8 Mb/s" : "850 kb/s"; }

const char* clockOffsetName(dw3000::ClockOffsetSource source) {
  switch (source) {
    case dw3000::ClockOffsetSource::kCiaDiag0: return "cia_diag0";
    case dw3000::ClockOffsetSource::kCarrierIntegrator: return "carrier_integrator";
    case dw3000::ClockOffsetSource::kNone: return "none";
  }
  return "?";
}

const char* partName(std::uint32_t dev_id) {
  if (dev_id == dw3000::kDevIdDw3110) return "DW3110";
  if (dev_id == dw3000::kDevIdDw3120) return "DW3120";
  return "unknown part";
}

std::string hex(std::uint32_t v, int digits) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%0*X", digits, static_cast<unsigned>(v));
  return text;
}

std::string i2cName(const ImuHardwareConfig& config) { return config.i2c_device + "@" + hex(config.i2c_address, 2); }

bool interrupted(const std::atomic<bool>* interrupt) {
  return interrupt != nullptr && interrupt->load(std::memory_order_relaxed);
}

// --- DWM3000 ------------------------------------------------------------------

void fillUwbConfig(const UwbHardwareConfig& config, UwbProbe& out) {
  const dw3000::Dw3000Config& c = config.dw3000;
  out.device = config.spi_device;
  out.channel = static_cast<int>(c.channel);
  out.preamble_code = c.preamble_code;
  out.preamble_length = c.preamble_length;
  out.data_rate = dataRateName(c.data_rate);
  out.tx_antenna_delay = c.tx_antenna_delay;
  out.rx_antenna_delay = c.rx_antenna_delay;
  out.clock_offset_source = clockOffsetName(c.clock_offset_source);
  out.reply_delay_us = c.reply_delay_us;
  for (const dw3000::AnchorConfig& a : c.anchors) {
    AnchorProbe probe;
    probe.id = a.id;
    probe.short_address = a.short_address;
    out.anchors.push_back(probe);
  }
}

void readUwbStatus(dw3000::Dw3000Device& device, UwbProbe& out) {
  out.dev_id = device.devId();
  out.spi_crc = device.spiCrcEnabled();
  out.irq_mask = device.irqMask();
  std::array<std::uint8_t, 2> tx_antd{};
  std::uint32_t cia_conf = 0;
  if (!device.read(dw3000::reg::kTxAntd, tx_antd)) {
    out.tx_antenna_delay_read = static_cast<std::uint16_t>(tx_antd[0] | (tx_antd[1] << 8));
  }
  if (!device.read32(dw3000::reg::kCiaConf, cia_conf)) out.rx_antenna_delay_read = static_cast<std::uint16_t>(cia_conf & 0xFFFF);
  (void)device.read32(dw3000::reg::kSysStatus, out.sys_status);
  (void)device.read32(dw3000::reg::kSysState, out.sys_state);
}

/// Brings the chip up; false (error filled) on failure.
bool bringUpUwb(dw3000::Dw3000Device& device, UwbProbe& out, const char* what) {
  try {
    device.bringUp();
    out.startup = device.bringUpReport();
    return true;
  } catch (const std::exception& e) {
    out.startup = device.bringUpReport();
    out.error = std::string("DWM3000 ") + what + " failed on " + out.device + ": " + e.what();
    return false;
  }
}

/// SS-TWR with every configured anchor in turn, each at the scheduler's
/// per-anchor rate, for `seconds`. No strongest-N selection: a bring-up wants
/// to see every anchor, weak ones included.
void measureUwb(dw3000::Dw3000Device& device, const dw3000::Dw3000Config& config, hal::Clock& clock, double seconds,
                const std::atomic<bool>* interrupt, UwbProbe& out) {
  const std::int64_t period_ns = std::max<std::int64_t>(1, secondsToNs(1.0 / config.scheduler.range_rate_hz));
  const std::int64_t start_ns = clock.nowNs();
  const std::int64_t end_ns = start_ns + secondsToNs(seconds);
  std::int64_t cycle_ns = start_ns;
  int device_faults_in_row = 0;
  while (clock.nowNs() < end_ns && !interrupted(interrupt)) {
    for (std::size_t i = 0; i < config.anchors.size() && clock.nowNs() < end_ns && !interrupted(interrupt); ++i) {
      AnchorProbe& anchor = out.anchors[i];
      ++anchor.attempts;
      const dw3000::ExchangeResult r = device.range(config.anchors[i]);
      bool reinit = false;
      if (r.status == dw3000::ExchangeStatus::kOk) {
        device_faults_in_row = 0;
        anchor.range_m.add(r.range_m);
        anchor.clock_offset_ppm.add(r.clock_offset_ratio * 1e6);
        // RX level and first-path power: range() read them with the response.
        if (r.diagnostics_error) ++out.device_faults["RX diagnostics read failed (range kept)"];
        if (std::isfinite(r.rx_power.rssi_dbm)) anchor.rssi_dbm.add(r.rx_power.rssi_dbm);
        if (std::isfinite(r.rx_power.fp_power_dbm)) anchor.fp_power_dbm.add(r.rx_power.fp_power_dbm);
        if (out.first_frames.size() < 3 && !r.diagnostics_error) {
          out.first_frames.push_back({anchor.id, r.range_m, r.diagnostics, r.rx_power.rssi_dbm, r.rx_power.fp_power_dbm});
        }
      } else if (dw3000::isDeviceFault(r.status)) {
        ++out.device_faults[dw3000::toString(r.status)];
        ++device_faults_in_row;
        reinit = r.status == dw3000::ExchangeStatus::kTxFailed ||
                 device_faults_in_row >= config.device_faults_before_reinit;
      } else {
        device_faults_in_row = 0;
        ++anchor.errors[dw3000::toString(r.status)];
      }
      if (r.irq == dw3000::IrqCheck::kRecovered) ++out.device_faults["IRQ high after clearing (recovered)"];
      if (r.irq == dw3000::IrqCheck::kStuck) {
        ++out.device_faults["IRQ stuck high"];
        reinit = true;
      }
      if (reinit) {
        ++out.reinitializations;
        device_faults_in_row = 0;
        if (!bringUpUwb(device, out, "re-initialization")) {
          out.up = false;
          break;
        }
      }
    }
    if (!out.up) break;
    cycle_ns += period_ns;
    const std::int64_t now_ns = clock.nowNs();
    if (cycle_ns > now_ns) {
      clock.sleepForNs(std::min(cycle_ns, end_ns) - now_ns);
    } else {
      cycle_ns = now_ns;  // slower than the rate (timeouts): no catching up
    }
  }
  out.seconds = static_cast<double>(clock.nowNs() - start_ns) * 1e-9;
}

void probeUwb(const UwbHardwareConfig& config, const UwbProbeTarget& target, double seconds,
              const std::atomic<bool>* interrupt, UwbProbe& out) {
  fillUwbConfig(config, out);
  if (!target.open_error.empty()) {
    out.error = target.open_error;
    return;
  }
  if (target.buses.spi == nullptr || target.buses.irq == nullptr || target.buses.clock == nullptr) {
    throw std::invalid_argument("runProbe: uwb.buses: the SPI device, IRQ line and clock are required");
  }
  out.opened = true;
  out.device = target.buses.spi->path();
  dw3000::Dw3000Device device(config.dw3000, *target.buses.spi, *target.buses.irq, target.buses.reset,
                              *target.buses.clock);
  if (!bringUpUwb(device, out, "bring-up")) return;
  out.up = true;
  readUwbStatus(device, out);
  measureUwb(device, config.dw3000, *target.buses.clock, seconds, interrupt, out);
}

// --- BMI263 -------------------------------------------------------------------

/// Accumulates the IMU stream and ends the run `seconds` after the first
/// sample (checked on every sample and fault: the source reports a fault at
/// least every irq_timeout_ns while no sample arrives).
class ImuProbeSink final : public SampleSink {
 public:
  ImuProbeSink(hal::Clock& clock, double seconds, const std::atomic<bool>* interrupt, ImuProbe& out)
      : clock_(clock),
        window_ns_(secondsToNs(seconds)),
        // No first sample this long after the start: give up (bring-up retries included).
        give_up_ns_(clock.nowNs() + window_ns_ + 5'000'000'000),
        interrupt_(interrupt),
        out_(out) {}

  void push(const Sample& sample) noexcept override {
    if (const auto* imu = std::get_if<ImuSample>(&sample)) add(*imu);
    checkDeadline();
  }

  void fault(const SourceFault& fault) noexcept override {
    ++out_.fault_count;
    if (out_.faults.size() < kMaxFaultMessages) {
      try {
        out_.faults.push_back((fault.fatal ? "[fatal] " : "") + fault.device + ": " + fault.what);
      } catch (...) {  // out of memory: the count is enough
      }
    }
    checkDeadline();
  }

  const std::atomic<bool>& stop() const { return stop_; }

  void finish() {
    ImuProbe& o = out_;
    if (o.samples == 0) return;
    const double n = static_cast<double>(o.samples);
    o.seconds = static_cast<double>(last_ns_ - first_ns_) * 1e-9;
    o.rate_hz = o.samples > 1 && o.seconds > 0.0 ? (n - 1.0) / o.seconds : 0.0;
    o.max_gap_ms = static_cast<double>(max_gap_ns_) * 1e-6;
    o.mean_accel_norm_m_s2 = accel_norm_sum_ / n;
    for (int k = 0; k < 3; ++k) {
      o.mean_accel_m_s2[static_cast<std::size_t>(k)] = accel_sum_[k] / n;
      o.mean_gyro_rad_s[static_cast<std::size_t>(k)] = gyro_sum_[k] / n;
    }
  }

 private:
  void add(const ImuSample& s) noexcept {
    if (out_.samples == 0) {
      first_ns_ = s.t_ns;
      deadline_ns_ = clock_.nowNs() + window_ns_;
    } else {
      max_gap_ns_ = std::max(max_gap_ns_, s.t_ns - last_ns_);
    }
    last_ns_ = s.t_ns;
    ++out_.samples;
    accel_sum_ += s.accel_m_s2;
    gyro_sum_ += s.gyro_rad_s;
    accel_norm_sum_ += s.accel_m_s2.norm();
  }

  void checkDeadline() noexcept {
    const std::int64_t now_ns = clock_.nowNs();
    const bool done = out_.samples > 0 ? now_ns >= deadline_ns_ : now_ns >= give_up_ns_;
    if (done || interrupted(interrupt_)) stop_.store(true, std::memory_order_relaxed);
  }

  hal::Clock& clock_;
  std::int64_t window_ns_;
  std::int64_t give_up_ns_;
  const std::atomic<bool>* interrupt_;
  ImuProbe& out_;
  std::atomic<bool> stop_{false};
  std::int64_t deadline_ns_ = 0;
  std::int64_t first_ns_ = 0;
  std::int64_t last_ns_ = 0;
  std::int64_t max_gap_ns_ = 0;
  Eigen::Vector3d accel_sum_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_sum_ = Eigen::Vector3d::Zero();
  double accel_norm_sum_ = 0.0;
};

void fillImuConfig(const ImuHardwareConfig& config, ImuProbe& out) {
  const bmi263::Bmi263Config& c = config.bmi263;
  out.device = i2cName(config);
  out.odr_hz = bmi263::odrHz(c.odr);
  out.accel_range_g = bmi263::accelRangeG(c.accel_range);
  out.gyro_range_dps = bmi263::gyroRangeDps(c.gyro_range);
  out.interrupt_mode = bmi263::toString(c.interrupt_mode);
}

/// Bring-up through the driver (for the chip id and INTERNAL_STATUS), then
/// the stream through the source rilod runs (its own bring-up, its time fit).
void probeImu(const ImuHardwareConfig& config, const ImuProbeTarget& target, double seconds,
              const std::atomic<bool>* interrupt, ImuProbe& out) {
  fillImuConfig(config, out);
  if (!target.open_error.empty()) {
    out.error = target.open_error;
    return;
  }
  if (target.buses.i2c == nullptr || target.buses.irq == nullptr || target.buses.clock == nullptr) {
    throw std::invalid_argument("runProbe: imu.buses: the I2C device, IRQ line and clock are required");
  }
  out.opened = true;
  out.device = target.buses.i2c->path();
  hal::Clock& clock = *target.buses.clock;
  {
    bmi263::Bmi263Driver driver(*target.buses.i2c, clock, config.bmi263);
    const bmi263::BringUpResult r = driver.bringUp();
    out.chip_id = r.chip_id;
    out.internal_status = r.internal_status;
    out.gyro_cross_axis = r.gyro_cross_axis;
    out.gyro_cas = r.gyro_cas;
    if (!r.ok) {
      out.error = "BMI263 bring-up failed on " + out.device + ": " + r.error;
      return;
    }
  }
  out.up = true;
  bmi263::Bmi263Source source(*target.buses.i2c, *target.buses.irq, clock, config.bmi263);
  ImuProbeSink sink(clock, seconds, interrupt, out);
  const SourceEnd end = source.run(sink, sink.stop());
  sink.finish();
  const bmi263::Bmi263Counters c = source.counters();
  out.temperature_degc = c.temperature_reads > 0 ? c.temperature_degc : std::numeric_limits<double>::quiet_NaN();
  out.missed_samples = c.missed_samples;
  out.i2c_retries = c.i2c_retries;
  out.i2c_failures = c.i2c_failures;
  out.recoveries = c.recoveries;
  if (end == SourceEnd::kFailed) {
    out.up = false;
    out.error = "BMI263 on " + out.device + " stopped: " + (out.faults.empty() ? "fatal fault" : out.faults.back());
  }
}

// --- text ---------------------------------------------------------------------

std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* fmt, ...) {
  char text[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(text, sizeof text, fmt, args);
  va_end(args);
  return text;
}

/// `v` with `decimals` digits after the point (and a sign if `sign`).
std::string fixed(double v, int decimals, bool sign = false) {
  return sign ? format("%+.*f", decimals, v) : format("%.*f", decimals, v);
}

std::string statOrDash(const RunningStats& s, int decimals, bool sign = false) {
  return s.count > 0 ? fixed(s.mean, decimals, sign) : std::string("-");
}

std::string countsText(const std::map<std::string, std::uint64_t>& counts) {
  std::string text;
  for (const auto& [kind, n] : counts) {
    if (!text.empty()) text += ", ";
    text += kind + " " + std::to_string(n);
  }
  return text.empty() ? std::string("none") : text;
}

// --- JSON (nlohmann-json: keys in the order written; NaN and inf dump as null) ---

using Json = nlohmann::ordered_json;

Json orNull(bool have, Json value) { return have ? std::move(value) : Json(nullptr); }

Json jsonStat(const RunningStats& s) { return orNull(s.count > 0, s.mean); }

Json jsonError(const std::string& e) { return orNull(!e.empty(), e); }

}  // namespace

void RunningStats::add(double x) noexcept {
  ++count;
  const double delta = x - mean;
  mean += delta / static_cast<double>(count);
  m2 += delta * (x - mean);
  min = std::min(min, x);
  max = std::max(max, x);
}

double RunningStats::stddev() const noexcept {
  return count > 1 ? std::sqrt(m2 / static_cast<double>(count - 1)) : 0.0;
}

double AnchorProbe::successRate() const noexcept {
  return attempts > 0 ? static_cast<double>(ranges()) / static_cast<double>(attempts) : 0.0;
}

std::vector<std::string> ProbeReport::problems() const {
  std::vector<std::string> p;
  if (!uwb.error.empty()) p.push_back(uwb.error);
  if (!imu.error.empty()) p.push_back(imu.error);
  if (uwb.up) {
    std::uint64_t ranges = 0;
    for (const AnchorProbe& a : uwb.anchors) ranges += a.ranges();
    if (ranges == 0) p.push_back("DWM3000 on " + uwb.device + ": no anchor answered (check the responders' short addresses, PAN id, channel and preamble code)");
  }
  if (imu.up && imu.samples == 0) p.push_back("BMI263 on " + imu.device + ": no sample arrived (check the INT1 line)");
  return p;
}

int ProbeReport::exitCode() const noexcept {
  if (!uwb.up || !imu.up) return 2;
  std::uint64_t ranges = 0;
  for (const AnchorProbe& a : uwb.anchors) ranges += a.ranges();
  return ranges == 0 || imu.samples == 0 ? 3 : 0;
}

ProbeReport runProbe(const HardwareSourceConfig& config, const UwbProbeTarget& uwb, const ImuProbeTarget& imu,
                     const ProbeOptions& options, const std::atomic<bool>* interrupt) {
  if (!(options.seconds > 0.0 && options.seconds <= 3600.0)) {
    throw std::invalid_argument("ProbeOptions: seconds must be in (0, 3600], got " + std::to_string(options.seconds));
  }
  ProbeReport report;
  // The IMU in its own thread while the UWB ranges here (as in rilod).
  std::exception_ptr imu_error;
  std::thread imu_thread([&] {
    try {
      probeImu(config.imu, imu, options.seconds, interrupt, report.imu);
    } catch (...) {
      imu_error = std::current_exception();
    }
  });
  std::exception_ptr uwb_error;
  try {
    probeUwb(config.uwb, uwb, options.seconds, interrupt, report.uwb);
  } catch (...) {
    uwb_error = std::current_exception();
  }
  imu_thread.join();
  if (uwb_error) std::rethrow_exception(uwb_error);
  if (imu_error) std::rethrow_exception(imu_error);
  return report;
}

std::string probeReportText(const ProbeReport& report) {
  std::string t;
  const UwbProbe& u = report.uwb;
  t += "DWM3000 on " + u.device + ": ";
  if (!u.opened || (!u.up && u.dev_id == 0)) {
    t += "FAILED\n  " + u.error + "\n";
  } else {
    t += std::string(u.up ? "up" : "FAILED") + "\n";
    if (!u.error.empty()) t += "  " + u.error + "\n";
    t += format("  DEV_ID %s (%s), SPI CRC %s, SYS_STATUS %s, SYS_STATE %s, IRQ mask %s\n", hex(u.dev_id, 8).c_str(),
                partName(u.dev_id), u.spi_crc ? "on" : "off", hex(u.sys_status, 8).c_str(),
                hex(u.sys_state, 8).c_str(), hex(u.irq_mask, 8).c_str());
    t += format("  channel %d, preamble code %d, %d symbols, %s; reply delay %.0f us, clock offset from %s\n", u.channel,
                u.preamble_code, u.preamble_length, u.data_rate.c_str(), u.reply_delay_us,
                u.clock_offset_source.c_str());
    t += format("  antenna delays: TX %u (read back %u), RX %u (read back %u) device units\n",
                static_cast<unsigned>(u.tx_antenna_delay), static_cast<unsigned>(u.tx_antenna_delay_read),
                static_cast<unsigned>(u.rx_antenna_delay), static_cast<unsigned>(u.rx_antenna_delay_read));
    t += "  start-up: " + dw3000::describe(u.startup) + "\n";
    t += format("  OTP: part id %s, lot id %s, revision %s\n", hex(u.startup.otp_part_id, 8).c_str(),
                hex(u.startup.otp_lot_id, 8).c_str(), hex(u.startup.otp_revision, 2).c_str());
    for (const FrameDiagnostics& f : u.first_frames) {
      t += format("  first frames: anchor %u at %.3f m: C %u, F1/F2/F3 %u/%u/%u, N %u, DGC %u -> RX level %s dBm, "
                  "first path %s dBm\n",
                  static_cast<unsigned>(f.anchor_id), f.range_m, static_cast<unsigned>(f.raw.cir_power),
                  static_cast<unsigned>(f.raw.fp_ampl1), static_cast<unsigned>(f.raw.fp_ampl2),
                  static_cast<unsigned>(f.raw.fp_ampl3), static_cast<unsigned>(f.raw.accumulation_count),
                  static_cast<unsigned>(f.raw.dgc_decision),
                  std::isfinite(f.rssi_dbm) ? format("%.1f", f.rssi_dbm).c_str() : "-",
                  std::isfinite(f.fp_power_dbm) ? format("%.1f", f.fp_power_dbm).c_str() : "-");
    }
    t += format("  ranging %.1f s, each anchor in turn:\n", u.seconds);
    t += format("  %6s %7s %6s %6s %5s %10s %9s %9s %9s %9s  %s\n", "anchor", "address", "polls", "ranges", "ok%",
                "mean (m)", "std (cm)", "RSSI dBm", "FP dBm", "offs ppm", "errors");
    for (const AnchorProbe& a : u.anchors) {
      t += format("  %6u %7s %6llu %6llu %5.1f %10s %9s %9s %9s %9s  %s\n", static_cast<unsigned>(a.id),
                  hex(a.short_address, 4).c_str(), static_cast<unsigned long long>(a.attempts),
                  static_cast<unsigned long long>(a.ranges()), 100.0 * a.successRate(),
                  statOrDash(a.range_m, 4).c_str(),
                  a.range_m.count > 1 ? format("%.2f", 100.0 * a.range_m.stddev()).c_str() : "-",
                  statOrDash(a.rssi_dbm, 1).c_str(), statOrDash(a.fp_power_dbm, 1).c_str(),
                  statOrDash(a.clock_offset_ppm, 2, true).c_str(), countsText(a.errors).c_str());
    }
    t += "  device faults: " + countsText(u.device_faults) + "; re-initializations " +
         std::to_string(u.reinitializations) + "\n";
  }
  const ImuProbe& m = report.imu;
  t += "BMI263 on " + m.device + ": ";
  if (!m.opened || (!m.up && m.chip_id == 0)) {
    t += "FAILED\n  " + m.error + "\n";
  } else {
    t += std::string(m.up ? "up" : "FAILED") + "\n";
    if (!m.error.empty()) t += "  " + m.error + "\n";
    t += format("  chip id %s, INTERNAL_STATUS %s (%s)\n", hex(m.chip_id, 2).c_str(), hex(m.internal_status, 2).c_str(),
                bmi263::internal_status::name(m.internal_status));
    t += format("  configured: %.0f Hz, +-%.0f g, +-%.0f dps, %s interrupt\n", m.odr_hz, m.accel_range_g,
                m.gyro_range_dps, m.interrupt_mode.c_str());
    t += m.gyro_cross_axis ? format("  gyro cross-axis correction: GYR_CAS %d (x -= %d z / 512)\n", m.gyro_cas, m.gyro_cas)
                           : std::string("  gyro cross-axis correction: off\n");
    if (m.samples > 0) {
      t += format("  %llu samples in %.2f s: %.1f Hz from the host timestamps (largest gap %.2f ms), %llu missed\n",
                  static_cast<unsigned long long>(m.samples), m.seconds, m.rate_hz, m.max_gap_ms,
                  static_cast<unsigned long long>(m.missed_samples));
      t += format("  mean |accel| %.4f m/s^2 (9.81 at rest); mean accel (%.4f, %.4f, %.4f) m/s^2\n",
                  m.mean_accel_norm_m_s2, m.mean_accel_m_s2[0], m.mean_accel_m_s2[1], m.mean_accel_m_s2[2]);
      constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;
      t += format("  mean gyro (%.5f, %.5f, %.5f) rad/s = (%.3f, %.3f, %.3f) deg/s\n", m.mean_gyro_rad_s[0],
                  m.mean_gyro_rad_s[1], m.mean_gyro_rad_s[2], m.mean_gyro_rad_s[0] * kDegPerRad,
                  m.mean_gyro_rad_s[1] * kDegPerRad, m.mean_gyro_rad_s[2] * kDegPerRad);
    } else if (m.up) {
      t += "  no samples\n";
    }
    if (std::isfinite(m.temperature_degc)) t += format("  temperature %.1f degC\n", m.temperature_degc);
    t += format("  I2C retries %llu, failures %llu, recoveries %llu, faults %llu\n",
                static_cast<unsigned long long>(m.i2c_retries), static_cast<unsigned long long>(m.i2c_failures),
                static_cast<unsigned long long>(m.recoveries), static_cast<unsigned long long>(m.fault_count));
    for (const std::string& f : m.faults) t += "    " + f + "\n";
  }
  const std::vector<std::string> problems = report.problems();
  if (problems.empty()) {
    t += "probe: OK\n";
  } else {
    for (const std::string& p : problems) t += "probe: " + p + "\n";
  }
  return t;
}

std::string probeReportJson(const ProbeReport& report) {
  const UwbProbe& u = report.uwb;
  const ImuProbe& m = report.imu;
  Json j;
  j["ok"] = report.exitCode() == 0;
  j["exit_code"] = report.exitCode();
  j["problems"] = report.problems();

  Json& uwb = j["uwb"];
  uwb["device"] = u.device;
  uwb["opened"] = u.opened;
  uwb["up"] = u.up;
  uwb["error"] = jsonError(u.error);
  uwb["dev_id"] = orNull(u.dev_id != 0, hex(u.dev_id, 8));
  uwb["part"] = orNull(u.dev_id != 0, partName(u.dev_id));
  uwb["channel"] = u.channel;
  uwb["preamble_code"] = u.preamble_code;
  uwb["preamble_length"] = u.preamble_length;
  uwb["data_rate"] = u.data_rate;
  uwb["tx_antenna_delay"] = u.tx_antenna_delay;
  uwb["rx_antenna_delay"] = u.rx_antenna_delay;
  uwb["tx_antenna_delay_read"] = u.tx_antenna_delay_read;
  uwb["rx_antenna_delay_read"] = u.rx_antenna_delay_read;
  uwb["spi_crc"] = u.spi_crc;
  uwb["sys_status"] = hex(u.sys_status, 8);
  uwb["sys_state"] = hex(u.sys_state, 8);
  uwb["irq_mask"] = hex(u.irq_mask, 8);
  uwb["clock_offset_source"] = u.clock_offset_source;
  uwb["reply_delay_us"] = u.reply_delay_us;
  const dw3000::BringUpReport& b = u.startup;
  uwb["startup"] = Json{{"otp_ldo_tune_lo", hex(b.otp_ldo_tune_lo, 8)},
                        {"otp_ldo_tune_hi", hex(b.otp_ldo_tune_hi, 8)},
                        {"otp_bias_tune", hex(b.otp_bias_tune, 2)},
                        {"ldo_bias_from_otp", b.ldo_bias_from_otp},
                        {"xtal_trim", hex(b.xtal_trim, 2)},
                        {"xtal_trim_from_otp", b.xtal_trim_from_otp},
                        {"otp_part_id", hex(b.otp_part_id, 8)},
                        {"otp_lot_id", hex(b.otp_lot_id, 8)},
                        {"otp_revision", hex(b.otp_revision, 2)},
                        {"pll_lock_us", orNull(b.pll_lock_ns >= 0, static_cast<double>(b.pll_lock_ns) * 1e-3)},
                        {"dgc_on", b.dgc_on},
                        {"dgc_from_otp", b.dgc_from_otp},
                        {"pgf_done", b.pgf_done},
                        {"pgf_result_i", hex(b.pgf_result_i, 8)},
                        {"pgf_result_q", hex(b.pgf_result_q, 8)}};
  Json frames = Json::array();
  for (const FrameDiagnostics& f : u.first_frames) {
    frames.push_back(Json{{"anchor", f.anchor_id},
                          {"range_m", f.range_m},
                          {"cir_power", f.raw.cir_power},
                          {"fp_ampl", {f.raw.fp_ampl1, f.raw.fp_ampl2, f.raw.fp_ampl3}},
                          {"accumulation_count", f.raw.accumulation_count},
                          {"dgc_decision", f.raw.dgc_decision},
                          {"rssi_dbm", f.rssi_dbm},
                          {"fp_power_dbm", f.fp_power_dbm}});
  }
  uwb["first_frames"] = std::move(frames);
  uwb["seconds"] = u.seconds;
  Json anchors = Json::array();
  for (const AnchorProbe& a : u.anchors) {
    anchors.push_back(Json{{"id", a.id},
                           {"short_address", hex(a.short_address, 4)},
                           {"polls", a.attempts},
                           {"ranges", a.ranges()},
                           {"success_rate", a.successRate()},
                           {"mean_range_m", jsonStat(a.range_m)},
                           {"std_range_m", orNull(a.range_m.count > 1, a.range_m.stddev())},
                           {"min_range_m", orNull(a.range_m.count > 0, a.range_m.min)},
                           {"max_range_m", orNull(a.range_m.count > 0, a.range_m.max)},
                           {"mean_rssi_dbm", jsonStat(a.rssi_dbm)},
                           {"mean_fp_power_dbm", jsonStat(a.fp_power_dbm)},
                           {"mean_clock_offset_ppm", jsonStat(a.clock_offset_ppm)},
                           {"errors", a.errors}});
  }
  uwb["anchors"] = std::move(anchors);
  uwb["device_faults"] = u.device_faults;
  uwb["reinitializations"] = u.reinitializations;

  Json& imu = j["imu"];
  imu["device"] = m.device;
  imu["opened"] = m.opened;
  imu["up"] = m.up;
  imu["error"] = jsonError(m.error);
  imu["chip_id"] = orNull(m.opened, hex(m.chip_id, 2));
  imu["internal_status"] = orNull(m.opened, hex(m.internal_status, 2));
  imu["internal_status_name"] = orNull(m.opened, bmi263::internal_status::name(m.internal_status));
  imu["odr_hz"] = m.odr_hz;
  imu["accel_range_g"] = m.accel_range_g;
  imu["gyro_range_dps"] = m.gyro_range_dps;
  imu["interrupt_mode"] = m.interrupt_mode;
  imu["gyro_cross_axis"] = m.gyro_cross_axis;
  imu["gyro_cas"] = orNull(m.gyro_cross_axis, m.gyro_cas);
  const bool have = m.samples > 0;
  imu["samples"] = m.samples;
  imu["seconds"] = m.seconds;
  imu["rate_hz"] = orNull(have, m.rate_hz);
  imu["max_gap_ms"] = orNull(have, m.max_gap_ms);
  imu["mean_accel_norm_m_s2"] = orNull(have, m.mean_accel_norm_m_s2);
  imu["mean_accel_m_s2"] = orNull(have, m.mean_accel_m_s2);
  imu["mean_gyro_rad_s"] = orNull(have, m.mean_gyro_rad_s);
  imu["temperature_degc"] = m.temperature_degc;
  imu["missed_samples"] = m.missed_samples;
  imu["i2c_retries"] = m.i2c_retries;
  imu["i2c_failures"] = m.i2c_failures;
  imu["recoveries"] = m.recoveries;
  imu["fault_count"] = m.fault_count;
  imu["faults"] = m.faults;
  // Device texts are not trusted to be UTF-8: bad bytes become U+FFFD, not an exception.
  return j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

}  // namespace rilo
