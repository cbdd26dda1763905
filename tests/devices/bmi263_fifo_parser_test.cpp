#include <gtest/gtest.h>

#include <vector>

#include "hal/bmi263/bmi263_fifo_parser.h"
#include "hal/bmi263/bmi263_registers.h"

namespace rilo::bmi263 {
namespace {

void appendFrame(std::vector<std::uint8_t>& bytes, std::int16_t base) {
  bytes.push_back(fifo::kHeaderAccGyr);
  for (int k = 0; k < 6; ++k) {  // gyro xyz then accel xyz
    const auto v = static_cast<std::uint16_t>(base + k);
    bytes.push_back(static_cast<std::uint8_t>(v & 0xFF));
    bytes.push_back(static_cast<std::uint8_t>(v >> 8));
  }
}

TEST(FifoParser, DataFramesThenSensortime) {
  std::vector<std::uint8_t> bytes = {fifo::kHeaderSkip, 3};
  appendFrame(bytes, 100);
  appendFrame(bytes, -200);
  bytes.insert(bytes.end(), {fifo::kHeaderSensorTime, 0x56, 0x34, 0x12, fifo::kHeaderEmpty, fifo::kHeaderEmpty});
  FifoParser parser(8);
  const FifoParseResult result = parser.parse(bytes);
  ASSERT_EQ(result.frame_count, 2u);
  EXPECT_EQ(result.skipped_frames, 3u);
  EXPECT_TRUE(result.has_sensortime);
  EXPECT_EQ(result.sensortime_raw, 0x123456u);
  EXPECT_TRUE(result.reached_end);
  const auto frames = parser.frames(result);
  EXPECT_EQ(frames[0].gyro_raw[0], 100);
  EXPECT_EQ(frames[0].gyro_raw[2], 102);
  EXPECT_EQ(frames[0].accel_raw[0], 103);
  EXPECT_EQ(frames[1].accel_raw[2], -195);
}

TEST(FifoParser, PartialTailUnknownHeaderAndCapacity) {
  std::vector<std::uint8_t> bytes;
  appendFrame(bytes, 1);
  appendFrame(bytes, 2);
  bytes.resize(bytes.size() - 5);  // second frame cut
  FifoParser parser(8);
  FifoParseResult result = parser.parse(bytes);
  EXPECT_EQ(result.frame_count, 1u);
  EXPECT_EQ(result.partial_tail_bytes, 8u);
  EXPECT_FALSE(result.reached_end);

  bytes = {fifo::kHeaderConfigChange, 0, 0, 0, 0, 0x17, 1, 2};
  result = parser.parse(bytes);
  EXPECT_EQ(result.config_changes, 1u);
  EXPECT_TRUE(result.unknown_header);
  EXPECT_EQ(result.bad_header, 0x17);

  bytes.clear();
  for (int i = 0; i < 3; ++i) appendFrame(bytes, 0);
  FifoParser small(2);
  result = small.parse(bytes);
  EXPECT_EQ(result.frame_count, 2u);
  EXPECT_EQ(result.frames_beyond_capacity, 1u);
}

}  // namespace
}  // namespace rilo::bmi263
