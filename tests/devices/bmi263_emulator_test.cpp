// The emulator at register level (no driver): what the driver tests rely on.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "bmi263_test_util.h"
#include "devices/emulation/bmi263_emulator.h"
#include "hal/bmi263/bmi263_registers.h"

namespace rilo::emu {
namespace {

namespace b = rilo::bmi263;
using rilo::bmi263::testing::makeBlob;
using rilo::bmi263::testing::smoothMotion;

class Bmi263EmulatorTest : public ::testing::Test {
 protected:
  explicit Bmi263EmulatorTest(Bmi263EmulatorConfig config = {}) : irq(clock, "emu:irq"), blob(makeBlob(8192, 1)) {
    config.expected_blob_checksum = Bmi263Emulator::checksum(blob);
    emu = std::make_unique<Bmi263Emulator>(clock, irq, smoothMotion, config);
  }
  std::uint8_t read1(std::uint8_t reg) {
    std::uint8_t v = 0;
    EXPECT_FALSE(emu->readRegisters(reg, std::span<std::uint8_t>(&v, 1)));
    return v;
  }
  void write1(std::uint8_t reg, std::uint8_t value) {
    const std::uint8_t data[1] = {value};
    EXPECT_FALSE(emu->writeRegisters(reg, data));
  }
  void upload(const std::vector<std::uint8_t>& bytes, std::size_t burst) {
    write1(b::reg::kInitCtrl, 0);
    for (std::size_t off = 0; off < bytes.size(); off += burst) {
      const std::uint8_t addr[2] = {static_cast<std::uint8_t>((off / 2) & 0x0F),
                                    static_cast<std::uint8_t>((off / 2) >> 4)};
      ASSERT_FALSE(emu->writeRegisters(b::reg::kInitAddr0, addr));
      const std::size_t n = std::min(burst, bytes.size() - off);
      ASSERT_FALSE(emu->writeRegisters(b::reg::kInitData, std::span<const std::uint8_t>(bytes.data() + off, n)));
    }
    write1(b::reg::kInitCtrl, 1);
  }

  VirtualClock clock;
  EmulatedInterruptLine irq;
  std::vector<std::uint8_t> blob;
  std::unique_ptr<Bmi263Emulator> emu;
};

TEST_F(Bmi263EmulatorTest, ChipIdResetAndBusyAfterReset) {
  EXPECT_EQ(read1(b::reg::kChipId), 0x24);
  EXPECT_EQ(read1(b::reg::kPwrConf), 0x03);
  write1(b::reg::kCmd, b::cmd::kSoftReset);
  std::uint8_t v = 0;
  EXPECT_EQ(emu->readRegisters(b::reg::kChipId, std::span<std::uint8_t>(&v, 1)),
            std::make_error_code(std::errc::no_such_device_or_address));
  clock.sleepForNs(2'000'000);
  EXPECT_EQ(read1(b::reg::kChipId), 0x24);
  EXPECT_EQ(emu->softResets(), 1u);
}

TEST_F(Bmi263EmulatorTest, ConfigLoadStateMachine) {
  write1(b::reg::kPwrConf, 0x00);
  upload(blob, 256);
  EXPECT_EQ(read1(b::reg::kInternalStatus), b::internal_status::kNotInit);  // still loading
  clock.sleepForNs(30'000'000);
  EXPECT_EQ(read1(b::reg::kInternalStatus), b::internal_status::kInitOk);

  // A wrong blob ends in init_err; so does a short one; and so does a load
  // with advanced power save still on.
  std::vector<std::uint8_t> wrong = blob;
  wrong[4000] ^= 0x01;
  upload(wrong, 128);
  clock.sleepForNs(30'000'000);
  EXPECT_EQ(read1(b::reg::kInternalStatus), b::internal_status::kInitErr);
  upload(std::vector<std::uint8_t>(blob.begin(), blob.begin() + 4096), 256);
  clock.sleepForNs(30'000'000);
  EXPECT_EQ(read1(b::reg::kInternalStatus), b::internal_status::kInitErr);
  write1(b::reg::kPwrConf, 0x03);
  upload(blob, 256);
  clock.sleepForNs(30'000'000);
  EXPECT_EQ(read1(b::reg::kInternalStatus), b::internal_status::kInitErr);
}

TEST_F(Bmi263EmulatorTest, DataReadyPulsesAtTheOdrWithSensortime) {
  write1(b::reg::kPwrConf, 0x00);
  upload(blob, 256);
  clock.sleepForNs(30'000'000);
  write1(b::reg::kAccConf, 0xAB);
  write1(b::reg::kGyrConf, 0xEB);
  write1(b::reg::kInt1IoCtrl, b::bits::kInt1PushPullActiveHigh);
  write1(b::reg::kIntMapData, b::bits::kIntMapDrdyInt1);
  write1(b::reg::kPwrCtrl, b::bits::kPwrCtrlAccGyrTemp);
  ASSERT_TRUE(emu->measuring());
  hal::EdgeEvent e1;
  hal::EdgeEvent e2;
  std::error_code error;
  ASSERT_EQ(irq.waitEdge(std::chrono::milliseconds(5), e1, error), hal::WaitResult::kEdge);
  ASSERT_EQ(irq.waitEdge(std::chrono::milliseconds(5), e2, error), hal::WaitResult::kEdge);
  EXPECT_NEAR(static_cast<double>(e2.t_ns - e1.t_ns), 1.25e6, 2.0);
  std::array<std::uint8_t, 15> burst{};
  ASSERT_FALSE(emu->readRegisters(b::reg::kAccDataX, burst));
  const std::uint32_t st = burst[12] | (burst[13] << 8) | (burst[14] << 16);
  EXPECT_EQ(st % 32, 0u);  // read at the sample instant
  EXPECT_EQ(emu->nearestSampleTimeNs(clock.nowNs() + 100'000), e2.t_ns);
  // Accel z ~ 1 g at the default +-8 g range (4096 LSB/g).
  const auto az = static_cast<std::int16_t>(burst[4] | (burst[5] << 8));
  const double expected = smoothMotion(e2.t_ns).accel_m_s2.z() / b::kStandardGravity * 4096.0;
  EXPECT_NEAR(az, expected, 0.51);
  // Temperature enabled: 31.5 degC.
  std::uint8_t temp[2] = {};
  ASSERT_FALSE(emu->readRegisters(b::reg::kTemperature0, temp));
  EXPECT_EQ(static_cast<std::int16_t>(temp[0] | (temp[1] << 8)), static_cast<std::int16_t>(8.5 * 512));
}

TEST_F(Bmi263EmulatorTest, OscillatorOffsetAndInjectedFaults) {
  Bmi263EmulatorConfig config;
  config.oscillator_ppm = 100.0;
  Bmi263Emulator fast(clock, irq, smoothMotion, config);
  const std::int64_t t0 = clock.nowNs();
  // 10 s of virtual time: 256000 nominal ticks, 25.6 more at +100 ppm.
  EXPECT_EQ(fast.ticksAt(t0 + 10'000'000'000) - fast.ticksAt(t0), 256'025);
  EXPECT_EQ(fast.ticksAt(fast.timeOfTick(1234567)), 1234567);
  EXPECT_EQ(fast.ticksAt(fast.timeOfTick(1234567) - 1), 1234566);

  const std::uint64_t next = emu->transactionCount();
  emu->failTransactions(next + 1, 2, std::make_error_code(std::errc::timed_out));
  std::uint8_t v = 0;
  EXPECT_FALSE(emu->readRegisters(0, std::span<std::uint8_t>(&v, 1)));
  EXPECT_EQ(emu->readRegisters(0, std::span<std::uint8_t>(&v, 1)), std::make_error_code(std::errc::timed_out));
  EXPECT_EQ(emu->readRegisters(0, std::span<std::uint8_t>(&v, 1)), std::make_error_code(std::errc::timed_out));
  EXPECT_FALSE(emu->readRegisters(0, std::span<std::uint8_t>(&v, 1)));
  emu->failNextOnRegister(b::reg::kPwrCtrl, 1, std::make_error_code(std::errc::io_error));
  EXPECT_FALSE(emu->readRegisters(0, std::span<std::uint8_t>(&v, 1)));
  const std::uint8_t on[1] = {0x0E};
  EXPECT_EQ(emu->writeRegisters(b::reg::kPwrCtrl, on), std::make_error_code(std::errc::io_error));
  EXPECT_EQ(emu->registerValue(b::reg::kPwrCtrl), 0x00);  // the failed write had no effect
  EXPECT_FALSE(emu->writeRegisters(b::reg::kPwrCtrl, on));
  EXPECT_EQ(emu->failedTransactions(), 3u);
}

TEST_F(Bmi263EmulatorTest, FifoWatermarkOverflowAndSensortimeFrame) {
  write1(b::reg::kPwrConf, 0x00);
  upload(blob, 256);
  clock.sleepForNs(30'000'000);
  write1(b::reg::kAccConf, 0xAB);
  write1(b::reg::kGyrConf, 0xEB);
  const std::uint8_t wtm[2] = {4 * 13, 0};
  ASSERT_FALSE(emu->writeRegisters(b::reg::kFifoWtm0, wtm));
  write1(b::reg::kFifoConfig1, 0xD0);
  write1(b::reg::kInt1IoCtrl, b::bits::kInt1PushPullActiveHigh);
  write1(b::reg::kIntMapData, b::bits::kIntMapFwmInt1);
  write1(b::reg::kPwrCtrl, b::bits::kPwrCtrlAccGyrTemp);
  hal::EdgeEvent edge;
  std::error_code error;
  ASSERT_EQ(irq.waitEdge(std::chrono::milliseconds(20), edge, error), hal::WaitResult::kEdge);
  EXPECT_EQ(emu->fifoBytes(), 4u * 13u);
  EXPECT_TRUE(irq.level());
  std::vector<std::uint8_t> bytes(4 * 13 + 4 + 2);
  ASSERT_FALSE(emu->readRegisters(b::reg::kFifoData, bytes));
  EXPECT_EQ(bytes[0], b::fifo::kHeaderAccGyr);
  EXPECT_EQ(bytes[52], b::fifo::kHeaderSensorTime);
  EXPECT_EQ(bytes[56], b::fifo::kHeaderEmpty);
  EXPECT_FALSE(irq.level());  // below the watermark again
  EXPECT_EQ(emu->fifoBytes(), 0u);

  // Leave it alone for 0.5 s: 400 frames into 2048 bytes, the oldest dropped.
  clock.sleepForNs(500'000'000);
  EXPECT_GT(emu->fifoFramesDropped(), 200u);
  std::uint8_t length[2] = {};
  ASSERT_FALSE(emu->readRegisters(b::reg::kFifoLength0, length));
  const std::size_t n = length[0] | (length[1] << 8);
  EXPECT_LE(n, 2048u);
  std::vector<std::uint8_t> all(n + 4);
  ASSERT_FALSE(emu->readRegisters(b::reg::kFifoData, all));
  EXPECT_EQ(all[0], b::fifo::kHeaderSkip);
  EXPECT_GT(all[1], 0);
  // Partial read: a frame cut in two is sent again next time.
  clock.sleepForNs(10'000'000);
  std::vector<std::uint8_t> part(20);
  ASSERT_FALSE(emu->readRegisters(b::reg::kFifoData, part));
  EXPECT_EQ(part[13], b::fifo::kHeaderAccGyr);
  std::vector<std::uint8_t> rest(13);
  ASSERT_FALSE(emu->readRegisters(b::reg::kFifoData, rest));
  EXPECT_TRUE(std::equal(rest.begin(), rest.begin() + 7, part.begin() + 13));
}

}  // namespace
}  // namespace rilo::emu
