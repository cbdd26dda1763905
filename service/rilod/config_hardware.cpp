// GCC 12 at -O3 reports the inlined copy of Bmi263Config's default
// accepted_chip_ids ({0x24, 0x27}, an initializer_list) as "may be used
// uninitialized" inside std::vector's memmove: a known false positive of the
// middle end (GCC PR 105562 family). Silenced for this file only.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include "rilod/config_hardware.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <string>

namespace rilo::config_detail {

namespace {

constexpr std::int64_t kMaxNs = 3'600'000'000'000;  // one hour: more is a typo in any timing key

bool isWordChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_'; }

/// True if `word` occurs in `text` delimited by non-identifier characters.
bool mentions(const std::string& text, const std::string& word) {
  for (std::size_t pos = text.find(word); pos != std::string::npos; pos = text.find(word, pos + 1)) {
    const bool left = pos == 0 || !isWordChar(text[pos - 1]);
    const std::size_t end = pos + word.size();
    const bool right = end >= text.size() || !isWordChar(text[end]);
    if (left && right) return true;
  }
  return false;
}

void collectMentioned(const ConfigField& field, const std::string& message, std::optional<ConfigField>& best,
                      std::size_t& best_length) {
  if (!field.node().IsMap()) return;
  for (auto it = field.node().begin(); it != field.node().end(); ++it) {
    if (!it->first.IsScalar()) continue;
    const std::string& key = it->first.Scalar();
    const ConfigField child(it->second, field.keyPath() + "." + key, &field.context());
    if (key.size() > best_length && mentions(message, key)) {
      best = child;
      best_length = key.size();
    }
    collectMentioned(child, message, best, best_length);
  }
}

/// Reports a driver validation message at the key it names (the longest key
/// of the section mentioned in it), or at the section.
[[noreturn]] void failAtMentionedKey(const ConfigField& section, const std::string& message) {
  std::optional<ConfigField> best;
  std::size_t best_length = 0;
  collectMentioned(section, message, best, best_length);
  (best ? *best : section).fail(message);
}

std::int64_t nanoseconds(const ConfigField& f) { return f.integer(0, kMaxNs); }
int count(const ConfigField& f) { return f.integerAs<int>(0, 1'000'000); }
std::size_t sizeValue(const ConfigField& f) { return f.integerAs<std::size_t>(0, 1u << 20); }
bool flag(const ConfigField& f) { return f.boolean(); }

std::string devicePath(const ConfigField& f) {
  const std::string path = f.string();
  if (path.rfind("/dev/", 0) != 0) f.fail("expected a device node path starting with /dev/, got '" + path + "'");
  return path;
}

GpioLineConfig readGpioLine(const ConfigField& field) {
  const ConfigMap m = field.map({"chip", "line"});
  GpioLineConfig g;
  m.read("chip", g.chip, [](const ConfigField& f) {
    const std::string chip = f.string();
    const bool by_name = chip.rfind("gpiochip", 0) == 0;
    const bool by_path = chip.rfind("/dev/", 0) == 0;
    if (!by_name && !by_path) f.fail("expected 'gpiochipN' or a /dev/ path, got '" + chip + "'");
    return chip;
  });
  g.line = m.require("line").integerAs<unsigned>(0, 1023);
  return g;
}

// --- DWM3000 -------------------------------------------------------------------

void readScheduler(const ConfigField& field, dw3000::AnchorSchedulerParams& s) {
  const ConfigMap m = field.map({"max_active", "range_rate_hz", "rediscovery_period_ns",
                                 "vacancy_rediscovery_period_ns", "hysteresis_db", "strength_smoothing",
                                 "max_failures", "backoff_initial_ns", "backoff_max_ns"});
  m.read("max_active", s.max_active, sizeValue);
  m.read("range_rate_hz", s.range_rate_hz, [](const ConfigField& f) { return f.positive(10'000.0); });
  m.read("rediscovery_period_ns", s.rediscovery_period_ns, nanoseconds);
  m.read("vacancy_rediscovery_period_ns", s.vacancy_rediscovery_period_ns, nanoseconds);
  m.read("hysteresis_db", s.hysteresis_db, [](const ConfigField& f) { return f.number(0.0, 100.0); });
  m.read("strength_smoothing", s.strength_smoothing, [](const ConfigField& f) { return f.number(0.0, 1.0); });
  m.read("max_failures", s.max_failures, count);
  m.read("backoff_initial_ns", s.backoff_initial_ns, nanoseconds);
  m.read("backoff_max_ns", s.backoff_max_ns, nanoseconds);
}

dw3000::AnchorConfig readResponder(const ConfigField& field) {
  const ConfigMap m = field.map({"id", "short_address"});
  dw3000::AnchorConfig a;
  a.id = m.require("id").integerAs<std::uint32_t>();
  a.short_address = m.require("short_address").integerAs<std::uint16_t>();
  return a;
}

dw3000::RegisterWrite readRegisterWrite(const ConfigField& field) {
  const ConfigMap m = field.map({"file", "offset", "value", "length"});
  dw3000::RegisterWrite w;
  w.addr.file = m.require("file").integerAs<std::uint8_t>(0, 0x1F);
  w.addr.offset = m.require("offset").integerAs<std::uint8_t>(0, 0x7F);
  w.value = m.require("value").integerAs<std::uint32_t>();
  m.read("length", w.length, [](const ConfigField& f) { return f.integerAs<std::uint8_t>(1, 4); });
  return w;
}

dw3000::Dw3000Config readDw3000(const ConfigField& field, const std::vector<Anchor>* surveyed) {
  using namespace dw3000;
  const ConfigMap m = field.map(
      {"channel", "preamble_code", "preamble_length", "data_rate", "sfd_type", "pac_symbols", "sfd_timeout_symbols",
       "pan_id", "tag_address", "tag_id", "anchors", "tx_antenna_delay", "rx_antenna_delay", "tx_pg_delay",
       "tx_power", "clock_offset_source", "reply_delay_us", "rx_after_tx_delay_us", "rx_timeout_us",
       "irq_wait_margin_ns", "spi_slow_hz", "spi_fast_hz", "spi_crc", "reset_low_ns", "boot_timeout_ns",
       "pll_lock_timeout_ns", "pgf_timeout_ns", "poll_interval_ns", "startup_audit", "extra_init_writes",
       "min_range_m", "max_range_m", "scheduler", "device_backoff_initial_ns", "device_backoff_max_ns",
       "device_faults_before_reinit", "startup_attempts", "max_reinit_failures"});
  Dw3000Config c;
  m.read("channel", c.channel, [](const ConfigField& f) {
    return f.choice<UwbChannel>({{"5", UwbChannel::k5}, {"9", UwbChannel::k9}});
  });
  m.read("preamble_code", c.preamble_code, [](const ConfigField& f) { return f.integerAs<std::uint8_t>(); });
  m.read("preamble_length", c.preamble_length, [](const ConfigField& f) { return f.integerAs<std::uint16_t>(); });
  m.read("data_rate", c.data_rate, [](const ConfigField& f) {
    return f.choice<DataRate>({{"850k", DataRate::k850k}, {"6m8", DataRate::k6M8}});
  });
  m.read("sfd_type", c.sfd_type, [](const ConfigField& f) { return f.integerAs<std::uint8_t>(0, 3); });
  m.read("pac_symbols", c.pac_symbols, [](const ConfigField& f) { return f.integerAs<std::uint8_t>(); });
  m.read("sfd_timeout_symbols", c.sfd_timeout_symbols, [](const ConfigField& f) { return f.integerAs<std::uint16_t>(); });
  m.read("pan_id", c.pan_id, [](const ConfigField& f) { return f.integerAs<std::uint16_t>(); });
  m.read("tag_address", c.tag_address, [](const ConfigField& f) { return f.integerAs<std::uint16_t>(); });
  m.read("tag_id", c.tag_id, [](const ConfigField& f) { return f.integerAs<std::uint32_t>(); });
  const ConfigField anchors = m.require("anchors");
  const std::vector<ConfigField> responders = anchors.sequence(1);
  for (const ConfigField& item : responders) c.anchors.push_back(readResponder(item));
  m.read("tx_antenna_delay", c.tx_antenna_delay, [](const ConfigField& f) { return f.integerAs<std::uint16_t>(); });
  m.read("rx_antenna_delay", c.rx_antenna_delay, [](const ConfigField& f) { return f.integerAs<std::uint16_t>(); });
  m.read("tx_pg_delay", c.tx_pg_delay, [](const ConfigField& f) { return f.integerAs<std::uint8_t>(0, 0x3F); });
  m.read("tx_power", c.tx_power, [](const ConfigField& f) { return f.integerAs<std::uint32_t>(); });
  m.read("clock_offset_source", c.clock_offset_source, [](const ConfigField& f) {
    return f.choice<ClockOffsetSource>({{"cia_diag0", ClockOffsetSource::kCiaDiag0},
                                        {"carrier_integrator", ClockOffsetSource::kCarrierIntegrator},
                                        {"none", ClockOffsetSource::kNone}});
  });
  auto microseconds = [](const ConfigField& f) { return f.number(0.0, 1e7); };
  m.read("reply_delay_us", c.reply_delay_us, microseconds);
  m.read("rx_after_tx_delay_us", c.rx_after_tx_delay_us, microseconds);
  m.read("rx_timeout_us", c.rx_timeout_us, microseconds);
  m.read("irq_wait_margin_ns", c.irq_wait_margin_ns, nanoseconds);
  m.read("spi_slow_hz", c.spi_slow_hz, [](const ConfigField& f) { return f.integerAs<std::uint32_t>(); });
  m.read("spi_fast_hz", c.spi_fast_hz, [](const ConfigField& f) { return f.integerAs<std::uint32_t>(); });
  m.read("spi_crc", c.spi_crc, flag);
  m.read("reset_low_ns", c.reset_low_ns, nanoseconds);
  m.read("boot_timeout_ns", c.boot_timeout_ns, nanoseconds);
  m.read("pll_lock_timeout_ns", c.pll_lock_timeout_ns, nanoseconds);
  m.read("pgf_timeout_ns", c.pgf_timeout_ns, nanoseconds);
  m.read("startup_audit", c.startup_audit, flag);
  m.read("poll_interval_ns", c.poll_interval_ns, nanoseconds);
  if (auto f = m.get("extra_init_writes")) {
    for (const ConfigField& item : f->sequence()) c.extra_init_writes.push_back(readRegisterWrite(item));
  }
  m.read("min_range_m", c.min_range_m, [](const ConfigField& f) { return f.number(-1e4, 1e4); });
  m.read("max_range_m", c.max_range_m, [](const ConfigField& f) { return f.number(-1e4, 1e4); });
  if (auto f = m.get("scheduler")) readScheduler(*f, c.scheduler);
  m.read("device_backoff_initial_ns", c.device_backoff_initial_ns, nanoseconds);
  m.read("device_backoff_max_ns", c.device_backoff_max_ns, nanoseconds);
  m.read("device_faults_before_reinit", c.device_faults_before_reinit, count);
  m.read("startup_attempts", c.startup_attempts, count);
  m.read("max_reinit_failures", c.max_reinit_failures, count);

  // Responders: distinct ids and addresses, each a surveyed UWB anchor.
  for (std::size_t i = 0; i < c.anchors.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (c.anchors[i].id == c.anchors[j].id) {
        responders[i].fail("anchor id " + std::to_string(c.anchors[i].id) + " repeats " + responders[j].keyPath());
      }
    }
    if (surveyed != nullptr) {
      const auto it = std::find_if(surveyed->begin(), surveyed->end(),
                                   [&](const Anchor& a) { return a.id == c.anchors[i].id; });
      if (it == surveyed->end()) {
        responders[i].fail("anchor id " + std::to_string(c.anchors[i].id) +
                           " is not among the surveyed anchors (the anchors section)");
      }
      if (it->kind != AnchorKind::kUwb) {
        responders[i].fail("anchor id " + std::to_string(c.anchors[i].id) + " is an ultrasonic anchor, not UWB");
      }
    }
  }
  try {
    validateConfig(c);
  } catch (const std::invalid_argument& e) {
    failAtMentionedKey(field, e.what());
  }
  return c;
}

// --- BMI263 --------------------------------------------------------------------

void readTimeFit(const ConfigField& field, bmi263::SensorTimeFitConfig& t) {
  const ConfigMap m = field.map({"window", "max_span_ticks", "min_span_ticks", "refit_every", "max_rate_error",
                                 "negative_outlier_ns", "positive_step_ns", "reset_after"});
  m.read("window", t.window, sizeValue);
  m.read("max_span_ticks", t.max_span_ticks, [](const ConfigField& f) { return f.integer(0, 1LL << 40); });
  m.read("min_span_ticks", t.min_span_ticks, [](const ConfigField& f) { return f.integer(0, 1LL << 40); });
  m.read("refit_every", t.refit_every, sizeValue);
  m.read("max_rate_error", t.max_rate_error, [](const ConfigField& f) { return f.number(0.0, 1.0); });
  m.read("negative_outlier_ns", t.negative_outlier_ns, nanoseconds);
  m.read("positive_step_ns", t.positive_step_ns, nanoseconds);
  m.read("reset_after", t.reset_after, sizeValue);
}

bmi263::Bmi263Config readBmi263(const ConfigField& field) {
  using namespace bmi263;
  const ConfigMap m = field.map(
      {"accepted_chip_ids", "config_blob_path", "expected_blob_bytes", "blob_burst_bytes", "odr_hz", "accel_range_g",
       "gyro_range_dps", "interrupt_mode", "fifo_watermark_frames", "fifo_read_max_bytes", "i2c_retries",
       "i2c_backoff_ns", "soft_reset_wait_ns", "power_conf_wait_ns", "init_wait_ns", "init_poll_ns",
       "init_timeout_ns", "sensor_startup_ns", "bring_up_attempts", "irq_timeout_ns",
       "max_consecutive_irq_timeouts", "max_consecutive_read_failures", "max_consecutive_irq_errors",
       "irq_error_backoff_ns", "temperature_period_ns", "sample_time_offset_ns", "pairing_tolerance_ns",
       "time_fit", "gyro_cross_axis"});
  Bmi263Config c;
  if (auto f = m.get("accepted_chip_ids")) {
    c.accepted_chip_ids.clear();
    for (const ConfigField& id : f->sequence(1)) c.accepted_chip_ids.push_back(id.integerAs<std::uint8_t>());
  }
  c.config_blob_path = m.require("config_blob_path").path().string();
  m.read("expected_blob_bytes", c.expected_blob_bytes, sizeValue);
  m.read("blob_burst_bytes", c.blob_burst_bytes, sizeValue);
  m.read("odr_hz", c.odr, [](const ConfigField& f) {
    return f.choice<Odr>({{"800", Odr::k800Hz}, {"1600", Odr::k1600Hz}});
  });
  m.read("gyro_cross_axis", c.gyro_cross_axis, [](const ConfigField& f) {
    return f.choice<GyroCrossAxis>({{"auto", GyroCrossAxis::kAuto}, {"on", GyroCrossAxis::kOn}, {"off", GyroCrossAxis::kOff}});
  });
  m.read("accel_range_g", c.accel_range, [](const ConfigField& f) {
    return f.choice<AccelRange>(
        {{"2", AccelRange::k2g}, {"4", AccelRange::k4g}, {"8", AccelRange::k8g}, {"16", AccelRange::k16g}});
  });
  m.read("gyro_range_dps", c.gyro_range, [](const ConfigField& f) {
    return f.choice<GyroRange>({{"125", GyroRange::k125dps},
                                {"250", GyroRange::k250dps},
                                {"500", GyroRange::k500dps},
                                {"1000", GyroRange::k1000dps},
                                {"2000", GyroRange::k2000dps}});
  });
  m.read("interrupt_mode", c.interrupt_mode, [](const ConfigField& f) {
    return f.choice<InterruptMode>(
        {{"data_ready", InterruptMode::kDataReady}, {"fifo_watermark", InterruptMode::kFifoWatermark}});
  });
  m.read("fifo_watermark_frames", c.fifo_watermark_frames, sizeValue);
  m.read("fifo_read_max_bytes", c.fifo_read_max_bytes, sizeValue);
  m.read("i2c_retries", c.i2c_retries, count);
  m.read("i2c_backoff_ns", c.i2c_backoff_ns, nanoseconds);
  m.read("soft_reset_wait_ns", c.soft_reset_wait_ns, nanoseconds);
  m.read("power_conf_wait_ns", c.power_conf_wait_ns, nanoseconds);
  m.read("init_wait_ns", c.init_wait_ns, nanoseconds);
  m.read("init_poll_ns", c.init_poll_ns, nanoseconds);
  m.read("init_timeout_ns", c.init_timeout_ns, nanoseconds);
  m.read("sensor_startup_ns", c.sensor_startup_ns, nanoseconds);
  m.read("bring_up_attempts", c.bring_up_attempts, count);
  m.read("irq_timeout_ns", c.irq_timeout_ns, nanoseconds);
  m.read("max_consecutive_irq_timeouts", c.max_consecutive_irq_timeouts, count);
  m.read("max_consecutive_read_failures", c.max_consecutive_read_failures, count);
  m.read("max_consecutive_irq_errors", c.max_consecutive_irq_errors, count);
  m.read("irq_error_backoff_ns", c.irq_error_backoff_ns, nanoseconds);
  m.read("temperature_period_ns", c.temperature_period_ns, nanoseconds);
  // May be negative: the offset is subtracted from fitted times.
  m.read("sample_time_offset_ns", c.sample_time_offset_ns,
         [](const ConfigField& f) { return f.integer(-1'000'000'000, 1'000'000'000); });
  m.read("pairing_tolerance_ns", c.pairing_tolerance_ns, nanoseconds);
  if (auto f = m.get("time_fit")) readTimeFit(*f, c.time_fit);
  try {
    c.validate();
  } catch (const std::invalid_argument& e) {
    failAtMentionedKey(field, e.what());
  }
  return c;
}

// --- devices -------------------------------------------------------------------

UwbHardwareConfig readUwb(const ConfigField& field, const std::vector<Anchor>* anchors) {
  const ConfigMap m = field.map({"spi_device", "irq", "reset", "dw3000"});
  UwbHardwareConfig c;
  m.read("spi_device", c.spi_device, devicePath);
  c.irq = readGpioLine(m.require("irq"));
  if (auto f = m.get("reset")) c.reset = readGpioLine(*f);
  c.dw3000 = readDw3000(m.require("dw3000"), anchors);
  return c;
}

ImuHardwareConfig readImuDevice(const ConfigField& field) {
  const ConfigMap m = field.map({"i2c_device", "address", "irq", "bmi263"});
  ImuHardwareConfig c;
  m.read("i2c_device", c.i2c_device, devicePath);
  m.read("address", c.i2c_address, [](const ConfigField& f) { return f.integerAs<std::uint8_t>(0x08, 0x77); });
  c.irq = readGpioLine(m.require("irq"));
  c.bmi263 = readBmi263(m.require("bmi263"));
  return c;
}

}  // namespace

HardwareSourceConfig readHardware(const ConfigField& field, const std::vector<Anchor>* anchors) {
  const ConfigMap m = field.map({"uwb", "imu"});
  HardwareSourceConfig c;
  c.uwb = readUwb(m.require("uwb"), anchors);
  c.imu = readImuDevice(m.require("imu"));
  const auto sameLine = [](const GpioLineConfig& a, const GpioLineConfig& b) {
    return a.chip == b.chip && a.line == b.line;
  };
  if (sameLine(c.uwb.irq, c.imu.irq) || (c.uwb.reset && (sameLine(*c.uwb.reset, c.uwb.irq) ||
                                                         sameLine(*c.uwb.reset, c.imu.irq)))) {
    field.fail("the UWB IRQ, UWB reset and IMU IRQ must be different GPIO lines");
  }
  return c;
}

}  // namespace rilo::config_detail
