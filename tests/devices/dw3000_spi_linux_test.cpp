// The spidev back-end cannot be exercised without a spidev node (none on
// development and CI machines); its failure paths can.
#include <gtest/gtest.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

#include "hal/bus/spi_linux.h"

namespace rilo::hal {
namespace {

std::string openError(const std::string& path) {
  try {
    SpiLinux spi(path, 2'000'000);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(Dw3000SpiLinux, MissingNodeNamesThePathAndTheErrno) {
  const std::string what = openError("/dev/spidev9.9-does-not-exist");
  EXPECT_NE(what.find("/dev/spidev9.9-does-not-exist"), std::string::npos) << what;
  EXPECT_NE(what.find("open"), std::string::npos) << what;
  EXPECT_NE(what.find(std::strerror(ENOENT)), std::string::npos) << what;
}

TEST(Dw3000SpiLinux, NodeThatIsNoSpidevFailsAtTheModeIoctl) {
  // /dev/null opens but rejects the SPI ioctls (ENOTTY).
  const std::string what = openError("/dev/null");
  EXPECT_NE(what.find("/dev/null"), std::string::npos) << what;
  EXPECT_NE(what.find("SPI_IOC_WR_MODE"), std::string::npos) << what;
  EXPECT_NE(what.find(std::strerror(ENOTTY)), std::string::npos) << what;
}

}  // namespace
}  // namespace rilo::hal
