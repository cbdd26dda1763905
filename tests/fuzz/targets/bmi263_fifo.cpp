// One BMI263 FIFO_DATA read (hal/bmi263/bmi263_fifo_parser.h): never reads
// past the bytes, never reports more frames than it holds.
#include <cstdlib>
#include <span>

#include "fuzz_targets.h"
#include "hal/bmi263/bmi263_fifo_parser.h"

namespace rilo::fuzz {

int bmi263Fifo(const std::uint8_t* data, std::size_t size) {
  static bmi263::FifoParser parser(64);
  const bmi263::FifoParseResult r = parser.parse(std::span<const std::uint8_t>(data, size));
  if (r.frame_count > 64 || r.partial_tail_bytes > size) std::abort();
  (void)parser.frames(r);
  return 0;
}

}  // namespace rilo::fuzz

RILO_FUZZ_ENTRY(bmi263Fifo)
