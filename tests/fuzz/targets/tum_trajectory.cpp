// TUM trajectory files (service/evaluation/tum.h), as rilo eval reads them.
#include <string_view>

#include "evaluation/tum.h"
#include "fuzz_targets.h"

namespace rilo::fuzz {

int tumTrajectory(const std::uint8_t* data, std::size_t size) {
  try {
    (void)parseTum(std::string_view(reinterpret_cast<const char*>(data), size), "trajectory.tum");
  } catch (const TumError&) {
  }
  return 0;
}

}  // namespace rilo::fuzz

RILO_FUZZ_ENTRY(tumTrajectory)
