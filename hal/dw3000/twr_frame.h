#pragma once
// The SS-TWR frames exchanged with the anchors (docs/uwb-protocol.md): IEEE
// 802.15.4 data frames, PAN id compression, 16-bit short addresses, followed
// by our function code and protocol version. The 2-byte FCS is appended by
// the chips and is not part of these buffers.
//
//   offset  size  field
//   0       2     frame control 0x8841 (bytes 0x41 0x88)
//   2       1     sequence number (response echoes the poll's)
//   3       2     PAN id (LE)
//   5       2     destination short address (LE)
//   7       2     source short address (LE)
//   9       1     function code: 0xA0 poll, 0xA1 response
//   10      1     protocol version (1)
//   response only:
//   11      5     responder's RX time of the poll (40 bit LE, its clock)
//   16      5     responder's TX time of the response (40 bit LE, its clock)
#include <cstddef>
#include <cstdint>
#include <span>

namespace rilo::dw3000 {

inline constexpr std::uint16_t kFrameControlData = 0x8841;
inline constexpr std::uint8_t kFunctionPoll = 0xA0;
inline constexpr std::uint8_t kFunctionResponse = 0xA1;
inline constexpr std::uint8_t kProtocolVersion = 1;
inline constexpr std::size_t kPollLength = 11;      ///< without FCS
inline constexpr std::size_t kResponseLength = 21;  ///< without FCS
inline constexpr std::size_t kFcsLength = 2;
inline constexpr std::uint16_t kBroadcastAddress = 0xFFFF;

struct PollFrame {
  std::uint8_t sequence = 0;
  std::uint16_t pan_id = 0;
  std::uint16_t destination = 0;  ///< anchor
  std::uint16_t source = 0;       ///< tag (us)
};

struct ResponseFrame {
  std::uint8_t sequence = 0;
  std::uint16_t pan_id = 0;
  std::uint16_t destination = 0;  ///< tag
  std::uint16_t source = 0;       ///< anchor
  std::uint64_t poll_rx = 0;      ///< 40 bit, responder clock
  std::uint64_t resp_tx = 0;      ///< 40 bit, responder clock
};

enum class FrameError : std::uint8_t {
  kOk,
  kWrongLength,
  kNotDataFrame,    ///< frame control is not our data-frame format
  kWrongFunction,
  kWrongVersion,
  // Match errors (set by the initiator, not by decode):
  kWrongAddress,    ///< PAN, destination or source is not this exchange's
  kWrongSequence,   ///< a stale response (sequence number of another poll)
};

const char* toString(FrameError error) noexcept;

/// Encode into `out` (at least kPollLength / kResponseLength bytes); returns
/// the length written, 0 if `out` is too small.
std::size_t encodePoll(const PollFrame& frame, std::span<std::uint8_t> out) noexcept;
std::size_t encodeResponse(const ResponseFrame& frame, std::span<std::uint8_t> out) noexcept;

/// Decode a frame without its FCS. Addresses and sequence are returned, not
/// checked: the caller matches them against what it sent.
FrameError decodePoll(std::span<const std::uint8_t> bytes, PollFrame& frame) noexcept;
FrameError decodeResponse(std::span<const std::uint8_t> bytes, ResponseFrame& frame) noexcept;

}  // namespace rilo::dw3000
