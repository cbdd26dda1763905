// The DW3000 two-way ranging frames (hal/dw3000/twr_frame.h): decoding any
// bytes is safe, and what decodes encodes back to the same bytes.
#include <array>
#include <cstdlib>
#include <cstring>
#include <span>

#include "fuzz_targets.h"
#include "hal/dw3000/twr_frame.h"

namespace rilo::fuzz {

int dw3000Frame(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  std::array<std::uint8_t, 64> again{};
  dw3000::PollFrame poll;
  if (dw3000::decodePoll(bytes, poll) == dw3000::FrameError::kOk) {
    const std::size_t n = dw3000::encodePoll(poll, again);
    if (n != size || std::memcmp(again.data(), data, n) != 0) std::abort();
  }
  dw3000::ResponseFrame response;
  if (dw3000::decodeResponse(bytes, response) == dw3000::FrameError::kOk) {
    const std::size_t n = dw3000::encodeResponse(response, again);
    if (n != size || std::memcmp(again.data(), data, n) != 0) std::abort();
  }
  return 0;
}

}  // namespace rilo::fuzz

RILO_FUZZ_ENTRY(dw3000Frame)
