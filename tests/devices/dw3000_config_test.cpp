#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "hal/dw3000/dw3000_config.h"

namespace rilo::dw3000 {
namespace {

Dw3000Config valid() {
  Dw3000Config c;
  c.anchors = {{1, 0x0001}, {2, 0x0002}};
  return c;
}

/// The message of the std::invalid_argument thrown for `c` ("" if none).
std::string errorOf(const Dw3000Config& c) {
  try {
    validateConfig(c);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Dw3000Config, DefaultsWithAnchorsAreValid) {
  EXPECT_EQ(errorOf(valid()), "");
  Dw3000Config ch9 = valid();
  ch9.channel = UwbChannel::k9;
  ch9.data_rate = DataRate::k850k;
  ch9.reply_delay_us = 1000.0;
  ch9.rx_after_tx_delay_us = 500.0;
  ch9.rx_timeout_us = 1000.0;
  EXPECT_EQ(errorOf(ch9), "");
}

TEST(Dw3000Config, ErrorsNameTheParameter) {
  Dw3000Config c = valid();
  c.anchors.clear();
  EXPECT_NE(errorOf(c).find("anchors"), std::string::npos);

  c = valid();
  c.anchors[1].short_address = c.anchors[0].short_address;
  EXPECT_NE(errorOf(c).find("anchors[1].short_address"), std::string::npos);

  c = valid();
  c.anchors[1].id = c.anchors[0].id;
  EXPECT_NE(errorOf(c).find("anchors[1].id"), std::string::npos);

  c = valid();
  c.anchors[0].short_address = c.tag_address;
  EXPECT_NE(errorOf(c).find("anchors[0].short_address"), std::string::npos);

  c = valid();
  c.spi_slow_hz = 8'000'000;
  EXPECT_NE(errorOf(c).find("spi_slow_hz"), std::string::npos);

  c = valid();
  c.spi_fast_hz = 1'000'000;
  EXPECT_NE(errorOf(c).find("spi_fast_hz"), std::string::npos);

  c = valid();
  c.preamble_length = 100;
  EXPECT_NE(errorOf(c).find("preamble_length"), std::string::npos);

  c = valid();
  c.rx_after_tx_delay_us = 400.0;  // opens after the response preamble starts
  EXPECT_NE(errorOf(c).find("rx_after_tx_delay_us"), std::string::npos);

  c = valid();
  c.rx_timeout_us = 100.0;  // closes before the response ends
  EXPECT_NE(errorOf(c).find("rx_timeout_us"), std::string::npos);

  c = valid();
  c.reply_delay_us = 50.0;
  EXPECT_NE(errorOf(c).find("reply_delay_us"), std::string::npos);

  c = valid();
  c.min_range_m = 5.0;
  c.max_range_m = 1.0;
  EXPECT_NE(errorOf(c).find("min_range_m"), std::string::npos);

  c = valid();
  c.extra_init_writes.push_back(RegisterWrite{{0x20, 0x00}, 0, 4});
  EXPECT_NE(errorOf(c).find("extra_init_writes[0].addr"), std::string::npos);

  c = valid();
  c.scheduler.max_active = 0;
  EXPECT_NE(errorOf(c).find("max_active"), std::string::npos);

  c = valid();
  c.scheduler.range_rate_hz = 0.0;
  EXPECT_NE(errorOf(c).find("range_rate_hz"), std::string::npos);

  c = valid();
  c.device_faults_before_reinit = 0;
  EXPECT_NE(errorOf(c).find("device_faults_before_reinit"), std::string::npos);

  c = valid();
  c.pac_symbols = 12;
  EXPECT_NE(errorOf(c).find("pac_symbols"), std::string::npos);

  c = valid();
  c.tx_pg_delay = 0x40;
  EXPECT_NE(errorOf(c).find("tx_pg_delay"), std::string::npos);

  c = valid();
  c.pgf_timeout_ns = 0;
  EXPECT_NE(errorOf(c).find("pgf_timeout_ns"), std::string::npos);
}

TEST(Dw3000Config, PacCodesAndTheSfdTimeoutFollowTheApi) {
  EXPECT_EQ(pacCode(8), 0);
  EXPECT_EQ(pacCode(16), 1);
  EXPECT_EQ(pacCode(32), 2);
  EXPECT_EQ(pacCode(4), 3);
  EXPECT_EQ(pacCode(5), -1);
  Dw3000Config c = valid();
  EXPECT_EQ(sfdTimeoutSymbols(c), 129);  // 128 + 1 + 8 - 8, the API examples' (129 + 8 - 8)
  c.preamble_length = 1024;
  c.pac_symbols = 32;
  c.sfd_type = 2;  // 16-symbol SFD
  EXPECT_EQ(sfdTimeoutSymbols(c), 1024 + 1 + 16 - 32);
  c.sfd_timeout_symbols = 500;
  EXPECT_EQ(sfdTimeoutSymbols(c), 500);
}

TEST(Dw3000Config, AirTimeEstimates) {
  Dw3000Config c = valid();
  EXPECT_NEAR(shrDurationUs(c), 136 * 1.01763, 1e-9);  // 128 preamble + 8 SFD symbols
  EXPECT_NEAR(payloadAirtimeUs(c, 13), 24.7 + (104.0 + 48.0) / 6.8, 0.1);
  c.data_rate = DataRate::k850k;
  EXPECT_NEAR(payloadAirtimeUs(c, 13), 24.7 + (104.0 + 48.0) / 0.85, 0.1);
  EXPECT_EQ(preambleLengthCode(128), 0x05);
  EXPECT_EQ(preambleLengthCode(64), 0x01);
  EXPECT_EQ(preambleLengthCode(100), -1);
}

}  // namespace
}  // namespace rilo::dw3000
