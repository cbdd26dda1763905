#pragma once
// Parser of one FIFO_DATA read in header mode (accel + gyro frames with
// sensortime): pure, allocation-free after construction, tested on its own.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace rilo::bmi263 {

struct FifoDataFrame {
  std::array<std::int16_t, 3> gyro_raw{};   ///< gyr xyz (frames carry gyro first)
  std::array<std::int16_t, 3> accel_raw{};  ///< acc xyz
};

struct FifoParseResult {
  std::size_t frame_count = 0;          ///< data frames in frames()[0, frame_count)
  std::uint32_t skipped_frames = 0;     ///< sum of skip-frame counts (FIFO overflow)
  std::uint32_t dropped_samples = 0;    ///< sum of sample-drop frame counts
  std::size_t config_changes = 0;
  bool has_sensortime = false;          ///< a sensortime frame followed the data
  std::uint32_t sensortime_raw = 0;     ///< its 24-bit value
  bool reached_end = false;             ///< saw the sensortime or an empty frame (FIFO drained)
  std::size_t partial_tail_bytes = 0;   ///< truncated frame at the end of the read (re-sent next read)
  bool unknown_header = false;          ///< a header we do not know: rest of the read discarded
  std::uint8_t bad_header = 0;
  std::size_t frames_beyond_capacity = 0;  ///< data frames that did not fit (not expected)
};

class FifoParser {
 public:
  /// Room for `max_frames` data frames per read (allocated once).
  explicit FifoParser(std::size_t max_frames);
  FifoParseResult parse(std::span<const std::uint8_t> bytes) noexcept;
  std::span<const FifoDataFrame> frames(const FifoParseResult& result) const noexcept {
    return {frames_.data(), result.frame_count};
  }

 private:
  std::vector<FifoDataFrame> frames_;
};

}  // namespace rilo::bmi263
