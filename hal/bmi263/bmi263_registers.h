#pragma once
// BMI263 (BMI270 family) register map, bit fields and codes, from
// shared/docs/hardware-notes.md section 2 (Bosch BMI2 sensor API, the Linux
// bmi270 driver). Shared by the driver and the register-level emulator so
// both speak the same map; values marked UNVERIFIED are to be checked on a
// BMI263 (see hal/bmi263/README.md).
#include <cstddef>
#include <cstdint>

namespace rilo::bmi263 {

namespace reg {
inline constexpr std::uint8_t kChipId = 0x00;
inline constexpr std::uint8_t kErrReg = 0x02;
inline constexpr std::uint8_t kStatus = 0x03;          ///< drdy_acc b7, drdy_gyr b6
inline constexpr std::uint8_t kAccDataX = 0x0C;        ///< acc xyz, then gyr xyz at 0x12, int16 LE
inline constexpr std::uint8_t kGyrDataX = 0x12;
inline constexpr std::uint8_t kSensorTime0 = 0x18;     ///< 24 bit LE, 0x18..0x1A
inline constexpr std::uint8_t kIntStatus1 = 0x1D;      ///< clear on read
inline constexpr std::uint8_t kInternalStatus = 0x21;  ///< message in bits 3:0
inline constexpr std::uint8_t kTemperature0 = 0x22;    ///< int16 LE, T = raw/512 + 23 degC
inline constexpr std::uint8_t kFifoLength0 = 0x24;     ///< 14-bit byte count, 0x24/0x25
inline constexpr std::uint8_t kFifoData = 0x26;        ///< read port (no auto-increment)
inline constexpr std::uint8_t kFeatPage = 0x2F;       ///< feature page shown at 0x30..0x3F
inline constexpr std::uint8_t kGyrCas = 0x3C;         ///< page 0 offset 0x0C: GYR_CAS, 7-bit signed (BMI270)
inline constexpr std::uint8_t kAccConf = 0x40;
inline constexpr std::uint8_t kAccRange = 0x41;
inline constexpr std::uint8_t kGyrConf = 0x42;
inline constexpr std::uint8_t kGyrRange = 0x43;
inline constexpr std::uint8_t kFifoDowns = 0x45;
inline constexpr std::uint8_t kFifoWtm0 = 0x46;        ///< watermark in bytes, 0x46/0x47
inline constexpr std::uint8_t kFifoConfig0 = 0x48;
inline constexpr std::uint8_t kFifoConfig1 = 0x49;
inline constexpr std::uint8_t kInt1IoCtrl = 0x53;
inline constexpr std::uint8_t kIntLatch = 0x55;
inline constexpr std::uint8_t kIntMapData = 0x58;
inline constexpr std::uint8_t kInitCtrl = 0x59;
inline constexpr std::uint8_t kInitAddr0 = 0x5B;       ///< word address bits 3:0; 0x5C: bits 11:4
inline constexpr std::uint8_t kInitAddr1 = 0x5C;
inline constexpr std::uint8_t kInitData = 0x5E;        ///< write port for the configuration blob
inline constexpr std::uint8_t kPwrConf = 0x7C;
inline constexpr std::uint8_t kPwrCtrl = 0x7D;
inline constexpr std::uint8_t kCmd = 0x7E;
}  // namespace reg

/// Data burst: acc xyz, gyr xyz (int16 LE), SENSORTIME (24 bit) = 15 bytes from 0x0C.
inline constexpr std::size_t kDataBurstBytes = 15;

namespace bits {
inline constexpr std::uint8_t kStatusDrdyAcc = 0x80;
inline constexpr std::uint8_t kStatusDrdyGyr = 0x40;
inline constexpr std::uint8_t kStatusCmdRdy = 0x10;
inline constexpr std::uint8_t kIntStatus1Fwm = 0x02;
inline constexpr std::uint8_t kIntStatus1Ffull = 0x01;
inline constexpr std::uint8_t kIntStatus1AccDrdy = 0x80;
inline constexpr std::uint8_t kIntStatus1GyrDrdy = 0x40;
inline constexpr std::uint8_t kPwrConfAdvPowerSave = 0x01;
inline constexpr std::uint8_t kPwrCtrlGyr = 0x02;
inline constexpr std::uint8_t kPwrCtrlAcc = 0x04;
inline constexpr std::uint8_t kPwrCtrlTemp = 0x08;
inline constexpr std::uint8_t kPwrCtrlAccGyrTemp = 0x0E;
inline constexpr std::uint8_t kConfOdrMask = 0x0F;
/// ACC_CONF: acc_filter_perf b7 (performance mode), acc_bwp 6:4 = 2 (normal).
inline constexpr std::uint8_t kAccConfPerformance = 0xA0;
/// GYR_CONF: gyr_filter_perf b7, gyr_noise_perf b6, gyr_bwp 5:4 = 2 (normal). UNVERIFIED on BMI263.
inline constexpr std::uint8_t kGyrConfPerformance = 0xE0;
inline constexpr std::uint8_t kFifoConfig0TimeEn = 0x02;
inline constexpr std::uint8_t kFifoConfig0StopOnFull = 0x01;
inline constexpr std::uint8_t kFifoConfig1HeaderEn = 0x10;
inline constexpr std::uint8_t kFifoConfig1AccEn = 0x40;
inline constexpr std::uint8_t kFifoConfig1GyrEn = 0x80;
/// FIFO_DOWNS: filtered accel (b7) and gyro (b3) data, no down-sampling. UNVERIFIED on BMI263.
inline constexpr std::uint8_t kFifoDownsFiltered = 0x88;
/// INT1_IO_CTRL: output_en b3, lvl b1 (active high), od b2 = 0 (push-pull).
inline constexpr std::uint8_t kInt1OutputEn = 0x08;
inline constexpr std::uint8_t kInt1ActiveHigh = 0x02;
inline constexpr std::uint8_t kInt1OpenDrain = 0x04;
inline constexpr std::uint8_t kInt1PushPullActiveHigh = 0x0A;
inline constexpr std::uint8_t kIntMapDrdyInt1 = 0x04;
inline constexpr std::uint8_t kIntMapFwmInt1 = 0x02;
inline constexpr std::uint8_t kIntMapFfullInt1 = 0x01;
}  // namespace bits

namespace cmd {
inline constexpr std::uint8_t kSoftReset = 0xB6;
inline constexpr std::uint8_t kFifoFlush = 0xB0;
}  // namespace cmd

/// INTERNAL_STATUS message (bits 3:0).
namespace internal_status {
inline constexpr std::uint8_t kMask = 0x0F;
inline constexpr std::uint8_t kNotInit = 0x00;
inline constexpr std::uint8_t kInitOk = 0x01;
inline constexpr std::uint8_t kInitErr = 0x02;
inline constexpr std::uint8_t kDrvErr = 0x03;
inline constexpr std::uint8_t kSnsStop = 0x04;
inline constexpr std::uint8_t kNvmError = 0x05;
inline constexpr std::uint8_t kStartUpError = 0x06;
inline constexpr std::uint8_t kCompatError = 0x07;
/// "init_err", "not_init", ...: for error messages.
inline const char* name(std::uint8_t status) {
  switch (status & kMask) {
    case kNotInit: return "not_init";
    case kInitOk: return "init_ok";
    case kInitErr: return "init_err";
    case kDrvErr: return "drv_err";
    case kSnsStop: return "sns_stop";
    case kNvmError: return "nvm_error";
    case kStartUpError: return "start_up_error";
    case kCompatError: return "compat_error";
    default: return "unknown";
  }
}
}  // namespace internal_status

/// ODR codes of ACC_CONF/GYR_CONF bits 3:0: rate = 100 Hz * 2^(code - 8).
namespace odr {
inline constexpr std::uint8_t k800Hz = 0x0B;
inline constexpr std::uint8_t k1600Hz = 0x0C;
/// Sensortime ticks per sample period for an ODR code (code 8 = 100 Hz =
/// 256 ticks; 800 Hz = 32, 1600 Hz = 16). 0 for codes outside 1..13.
constexpr std::int64_t periodTicks(std::uint8_t code) {
  if (code < 1 || code > 13) return 0;
  return code <= 8 ? std::int64_t{256} << (8 - code) : std::int64_t{256} >> (code - 8);
}
}  // namespace odr

/// FIFO frame headers (header mode).
namespace fifo {
inline constexpr std::uint8_t kHeaderAccGyr = 0x8C;     ///< 12 bytes: gyr xyz then acc xyz
inline constexpr std::uint8_t kHeaderSensorTime = 0x44; ///< 3 bytes sensortime
inline constexpr std::uint8_t kHeaderSkip = 0x40;       ///< 1 byte: frames dropped
inline constexpr std::uint8_t kHeaderConfigChange = 0x48;  ///< 4 bytes (UNVERIFIED length)
inline constexpr std::uint8_t kHeaderSampleDrop = 0x50; ///< 1 byte
inline constexpr std::uint8_t kHeaderEmpty = 0x80;      ///< read past the end
inline constexpr std::size_t kAccGyrFrameBytes = 13;
inline constexpr std::size_t kSensorTimeFrameBytes = 4;
}  // namespace fifo

/// SENSORTIME: 24 bit, 39.0625 us per tick (25.6 kHz), wraps after 655.36 s.
inline constexpr std::uint32_t kSensorTimeMask = 0xFFFFFF;
inline constexpr std::int64_t kSensorTimeModulus = std::int64_t{1} << 24;
inline constexpr double kSensorTimeTickNs = 39062.5;

inline constexpr double kStandardGravity = 9.80665;  ///< m/s^2 per g

}  // namespace rilo::bmi263
