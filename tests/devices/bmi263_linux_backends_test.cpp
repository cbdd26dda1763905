// The Linux back-ends cannot talk to hardware here (no i2c-dev or gpiochip
// nodes); what can be checked is that opening fails with a clear message.
#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>
#include <string>

#include "hal/bus/gpio_linux.h"
#include "hal/bus/i2c_linux.h"

namespace rilo::hal {
namespace {

std::string whatOf(const std::function<void()>& action) {
  try {
    action();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(I2cLinux, MissingNodeNamesThePathAndTheErrno) {
  EXPECT_THROW(I2cLinux("/dev/i2c-rilo-missing", 0x68), std::runtime_error);
  const std::string text = whatOf([] { I2cLinux bus("/dev/i2c-rilo-missing", 0x68); });
  EXPECT_NE(text.find("/dev/i2c-rilo-missing"), std::string::npos) << text;
  EXPECT_NE(text.find("@0x68"), std::string::npos) << text;
  EXPECT_NE(text.find("No such file or directory"), std::string::npos) << text;
}

TEST(I2cLinux, NodeThatIsNotAnAdapterIsRejected) {
  // /dev/null opens but answers no I2C ioctl.
  EXPECT_THROW(I2cLinux("/dev/null", 0x69), std::runtime_error);
  const std::string text = whatOf([] { I2cLinux bus("/dev/null", 0x69); });
  EXPECT_NE(text.find("/dev/null"), std::string::npos) << text;
  EXPECT_NE(text.find("not an i2c-dev adapter"), std::string::npos) << text;
}

TEST(I2cLinux, BadParametersAreNamed) {
  EXPECT_THROW(I2cLinux("/dev/i2c-1", 0x80), std::invalid_argument);
  EXPECT_NE(whatOf([] { I2cLinux bus("/dev/i2c-1", 0x03); }).find("address"), std::string::npos);
  EXPECT_NE(whatOf([] { I2cLinux bus("/dev/i2c-1", 0x68, 1); }).find("max_message_bytes"), std::string::npos);
}

TEST(GpioLinux, MissingChipByNameNamesChipLineAndErrno) {
  const std::string text = whatOf([] { GpioInterruptLine line("gpiochip-rilo-missing", 17); });
  EXPECT_NE(text.find("gpiochip-rilo-missing"), std::string::npos) << text;
  EXPECT_NE(text.find("/dev/gpiochip-rilo-missing"), std::string::npos) << text;
  EXPECT_NE(text.find("line 17"), std::string::npos) << text;
  EXPECT_NE(text.find("No such file or directory"), std::string::npos) << text;
  EXPECT_THROW(GpioInterruptLine("gpiochip-rilo-missing", 17), std::runtime_error);
}

TEST(GpioLinux, MissingChipByPathAndOutputLine) {
  const std::string text = whatOf([] { GpioInterruptLine line("/nonexistent/gpiochip0", 4); });
  EXPECT_NE(text.find("/nonexistent/gpiochip0"), std::string::npos) << text;
  EXPECT_NE(text.find("No such file or directory"), std::string::npos) << text;
  const std::string out = whatOf([] { GpioOutputLine line("gpiochip-rilo-missing", 5, true); });
  EXPECT_NE(out.find("gpiochip-rilo-missing"), std::string::npos) << out;
  EXPECT_NE(out.find("line 5"), std::string::npos) << out;
  EXPECT_THROW(GpioOutputLine("gpiochip-rilo-missing", 5, false), std::runtime_error);
}

TEST(GpioLinux, NonChipDeviceIsRejected) {
  EXPECT_THROW(GpioInterruptLine("/dev/null", 0), std::runtime_error);
  EXPECT_THROW(GpioInterruptLine("", 0), std::invalid_argument);
}

}  // namespace
}  // namespace rilo::hal
