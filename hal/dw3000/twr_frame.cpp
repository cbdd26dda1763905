#include "hal/dw3000/twr_frame.h"

#include "hal/dw3000/timestamp.h"

namespace rilo::dw3000 {
namespace {

void put16(std::uint16_t v, std::uint8_t* p) {
  p[0] = static_cast<std::uint8_t>(v & 0xFFu);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
std::uint16_t get16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}

void putHeader(std::uint8_t sequence, std::uint16_t pan, std::uint16_t dst, std::uint16_t src, std::uint8_t function,
               std::uint8_t* p) {
  put16(kFrameControlData, p);
  p[2] = sequence;
  put16(pan, p + 3);
  put16(dst, p + 5);
  put16(src, p + 7);
  p[9] = function;
  p[10] = kProtocolVersion;
}

FrameError checkHeader(std::span<const std::uint8_t> bytes, std::size_t length, std::uint8_t function) {
  if (bytes.size() != length) return FrameError::kWrongLength;
  if (get16(bytes.data()) != kFrameControlData) return FrameError::kNotDataFrame;
  if (bytes[9] != function) return FrameError::kWrongFunction;
  if (bytes[10] != kProtocolVersion) return FrameError::kWrongVersion;
  return FrameError::kOk;
}

}  // namespace

const char* toString(FrameError error) noexcept {
  switch (error) {
    case FrameError::kOk: return "ok";
    case FrameError::kWrongLength: return "wrong length";
    case FrameError::kNotDataFrame: return "not a data frame of our format";
    case FrameError::kWrongFunction: return "unexpected function code";
    case FrameError::kWrongVersion: return "unsupported protocol version";
    case FrameError::kWrongAddress: return "addressed to another device or PAN";
    case FrameError::kWrongSequence: return "sequence number of another poll";
  }
  return "?";
}

std::size_t encodePoll(const PollFrame& frame, std::span<std::uint8_t> out) noexcept {
  if (out.size() < kPollLength) return 0;
  putHeader(frame.sequence, frame.pan_id, frame.destination, frame.source, kFunctionPoll, out.data());
  return kPollLength;
}

std::size_t encodeResponse(const ResponseFrame& frame, std::span<std::uint8_t> out) noexcept {
  if (out.size() < kResponseLength) return 0;
  putHeader(frame.sequence, frame.pan_id, frame.destination, frame.source, kFunctionResponse, out.data());
  writeTimestamp40(frame.poll_rx & kTimestampMask, out.data() + 11);
  writeTimestamp40(frame.resp_tx & kTimestampMask, out.data() + 16);
  return kResponseLength;
}

FrameError decodePoll(std::span<const std::uint8_t> bytes, PollFrame& frame) noexcept {
  const FrameError e = checkHeader(bytes, kPollLength, kFunctionPoll);
  if (e != FrameError::kOk) return e;
  frame.sequence = bytes[2];
  frame.pan_id = get16(bytes.data() + 3);
  frame.destination = get16(bytes.data() + 5);
  frame.source = get16(bytes.data() + 7);
  return FrameError::kOk;
}

FrameError decodeResponse(std::span<const std::uint8_t> bytes, ResponseFrame& frame) noexcept {
  const FrameError e = checkHeader(bytes, kResponseLength, kFunctionResponse);
  if (e != FrameError::kOk) return e;
  frame.sequence = bytes[2];
  frame.pan_id = get16(bytes.data() + 3);
  frame.destination = get16(bytes.data() + 5);
  frame.source = get16(bytes.data() + 7);
  frame.poll_rx = readTimestamp40(bytes.data() + 11);
  frame.resp_tx = readTimestamp40(bytes.data() + 16);
  return FrameError::kOk;
}

}  // namespace rilo::dw3000
