#include "estimation/measurements/tag_lever_arms.h"

#include <stdexcept>
#include <string>

namespace rilo {

void validateTagLeverArms(const std::vector<TagLeverArm>& arms, const char* where) {
  for (std::size_t i = 0; i < arms.size(); ++i) {
    const std::string tag = std::string(where) + "tag_lever_arms: tag " + std::to_string(arms[i].tag_id);
    if (!arms[i].p_b_m.allFinite()) throw std::invalid_argument(tag + " has a non-finite lever arm");
    for (std::size_t j = 0; j < i; ++j) {
      if (arms[j].tag_id == arms[i].tag_id) throw std::invalid_argument(tag + " is listed twice");
    }
  }
}

}  // namespace rilo
