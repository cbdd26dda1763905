#include "hal/bmi263/bmi263_fifo_parser.h"

#include "hal/bmi263/bmi263_registers.h"

namespace rilo::bmi263 {
namespace {

std::int16_t le16(const std::uint8_t* p) noexcept {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0] | (p[1] << 8)));
}

}  // namespace

FifoParser::FifoParser(std::size_t max_frames) : frames_(max_frames) {}

FifoParseResult FifoParser::parse(std::span<const std::uint8_t> bytes) noexcept {
  FifoParseResult result;
  std::size_t i = 0;
  while (i < bytes.size()) {
    const std::uint8_t header = bytes[i];
    const std::size_t left = bytes.size() - i;
    std::size_t frame_bytes = 0;
    switch (header) {
      case fifo::kHeaderAccGyr: frame_bytes = fifo::kAccGyrFrameBytes; break;
      case fifo::kHeaderSensorTime: frame_bytes = fifo::kSensorTimeFrameBytes; break;
      case fifo::kHeaderSkip: frame_bytes = 2; break;
      case fifo::kHeaderSampleDrop: frame_bytes = 2; break;
      case fifo::kHeaderConfigChange: frame_bytes = 5; break;
      case fifo::kHeaderEmpty:
        result.reached_end = true;
        return result;
      default:
        result.unknown_header = true;
        result.bad_header = header;
        return result;
    }
    if (left < frame_bytes) {
      result.partial_tail_bytes = left;
      return result;
    }
    const std::uint8_t* p = bytes.data() + i + 1;
    switch (header) {
      case fifo::kHeaderAccGyr:
        if (result.frame_count < frames_.size()) {
          FifoDataFrame& frame = frames_[result.frame_count++];
          for (int axis = 0; axis < 3; ++axis) {
            frame.gyro_raw[static_cast<std::size_t>(axis)] = le16(p + 2 * axis);
            frame.accel_raw[static_cast<std::size_t>(axis)] = le16(p + 6 + 2 * axis);
          }
        } else {
          ++result.frames_beyond_capacity;
        }
        break;
      case fifo::kHeaderSensorTime:
        result.has_sensortime = true;
        result.sensortime_raw = static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
                                (static_cast<std::uint32_t>(p[2]) << 16);
        // The sensortime frame comes after the last stored frame: the FIFO is drained.
        result.reached_end = true;
        return result;
      case fifo::kHeaderSkip: result.skipped_frames += p[0]; break;
      case fifo::kHeaderSampleDrop: result.dropped_samples += p[0]; break;
      case fifo::kHeaderConfigChange: ++result.config_changes; break;
      default: break;
    }
    i += frame_bytes;
  }
  return result;
}

}  // namespace rilo::bmi263
