#include <gtest/gtest.h>

#include <array>
#include <cstdint>

#include "hal/dw3000/twr_frame.h"

namespace rilo::dw3000 {
namespace {

TEST(Dw3000Frame, PollBytesAreTheDocumentedLayout) {
  std::array<std::uint8_t, kPollLength> bytes{};
  ASSERT_EQ(encodePoll(PollFrame{0x12, 0xDECA, 0x0003, 0x8000}, bytes), kPollLength);
  const std::array<std::uint8_t, kPollLength> expected{0x41, 0x88, 0x12, 0xCA, 0xDE, 0x03,
                                                       0x00, 0x00, 0x80, 0xA0, 0x01};
  EXPECT_EQ(bytes, expected);
  PollFrame decoded;
  ASSERT_EQ(decodePoll(bytes, decoded), FrameError::kOk);
  EXPECT_EQ(decoded.sequence, 0x12);
  EXPECT_EQ(decoded.pan_id, 0xDECA);
  EXPECT_EQ(decoded.destination, 0x0003);
  EXPECT_EQ(decoded.source, 0x8000);
}

TEST(Dw3000Frame, ResponseCarries40BitStamps) {
  ResponseFrame frame;
  frame.sequence = 200;
  frame.pan_id = 0xDECA;
  frame.destination = 0x8000;
  frame.source = 0x0003;
  frame.poll_rx = 0xFF'FFFF'FFF0ull;
  frame.resp_tx = 0x00'0000'1234ull;
  std::array<std::uint8_t, kResponseLength> bytes{};
  ASSERT_EQ(encodeResponse(frame, bytes), kResponseLength);
  EXPECT_EQ(bytes[9], kFunctionResponse);
  EXPECT_EQ(bytes[11], 0xF0);
  EXPECT_EQ(bytes[15], 0xFF);
  EXPECT_EQ(bytes[16], 0x34);
  EXPECT_EQ(bytes[17], 0x12);
  ResponseFrame decoded;
  ASSERT_EQ(decodeResponse(bytes, decoded), FrameError::kOk);
  EXPECT_EQ(decoded.sequence, 200);
  EXPECT_EQ(decoded.destination, 0x8000);
  EXPECT_EQ(decoded.source, 0x0003);
  EXPECT_EQ(decoded.poll_rx, frame.poll_rx);
  EXPECT_EQ(decoded.resp_tx, frame.resp_tx);
}

TEST(Dw3000Frame, DecodeNamesWhatIsWrong) {
  std::array<std::uint8_t, kResponseLength> bytes{};
  encodeResponse(ResponseFrame{}, bytes);
  ResponseFrame out;
  EXPECT_EQ(decodeResponse(std::span<const std::uint8_t>(bytes).first(kResponseLength - 1), out),
            FrameError::kWrongLength);
  auto bad = bytes;
  bad[0] = 0x61;  // ACK request set: not our frame control
  EXPECT_EQ(decodeResponse(bad, out), FrameError::kNotDataFrame);
  bad = bytes;
  bad[9] = kFunctionPoll;
  EXPECT_EQ(decodeResponse(bad, out), FrameError::kWrongFunction);
  bad = bytes;
  bad[10] = 2;
  EXPECT_EQ(decodeResponse(bad, out), FrameError::kWrongVersion);
  std::array<std::uint8_t, kPollLength> poll{};
  encodePoll(PollFrame{}, poll);
  EXPECT_EQ(decodeResponse(poll, out), FrameError::kWrongLength);
  PollFrame p;
  EXPECT_EQ(decodePoll(std::span<const std::uint8_t>(bytes).first(kPollLength), p), FrameError::kWrongFunction);
  std::array<std::uint8_t, 4> small{};
  EXPECT_EQ(encodePoll(PollFrame{}, small), 0u);
  EXPECT_STREQ(toString(FrameError::kWrongSequence), "sequence number of another poll");
}

}  // namespace
}  // namespace rilo::dw3000
