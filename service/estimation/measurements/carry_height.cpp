#include "estimation/measurements/carry_height.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rilo {

CarryHeight::CarryHeight(const HeightBand& band, bool learn) : band_(band), learn_(learn), height_m_(band.midZ()) {
  if (!(band.carry_memory_s > 0.0)) throw std::invalid_argument("HeightBand.carry_memory_s must be positive");
  const double sigma_m = 0.25 * (band.max_height_m - band.min_height_m);
  prior_info_ = sigma_m > 0.0 ? 1.0 / (sigma_m * sigma_m) : 1.0;
}

void CarryHeight::addEvidence(std::uint64_t index, double info) {
  if (!learn_ || !(info > 0.0) || !std::isfinite(info)) return;
  if (!pending_.empty() && pending_.back().first == index) {
    pending_.back().second += info;
  } else {
    pending_.push_back({index, info});
  }
}

void CarryHeight::notePostFit(std::uint64_t index, std::int64_t t_ns, double z_tag_m) {
  if (!learn_) return;
  // Fade first, on every post-fit: where no range tells the height the
  // learnt part goes back to the middle over memory_s.
  if (have_time_ && t_ns > last_t_ns_) {
    const double fade = std::exp(-1e-9 * static_cast<double>(t_ns - last_t_ns_) / band_.carry_memory_s);
    info_ *= fade;
    info_z_ *= fade;
  }
  last_t_ns_ = have_time_ ? std::max(last_t_ns_, t_ns) : t_ns;
  have_time_ = true;
  while (!pending_.empty() && pending_.front().first < index) pending_.pop_front();
  if (!pending_.empty() && pending_.front().first == index) {
    const double info = pending_.front().second;
    pending_.pop_front();
    if (std::isfinite(z_tag_m)) {
      // Heights outside the band are the band's to correct, not evidence.
      const double z_m = std::clamp(z_tag_m, band_.minZ(), band_.maxZ());
      info_ += info;
      info_z_ += info * z_m;
    }
  }
  height_m_ = (prior_info_ * band_.midZ() + info_z_) / (prior_info_ + info_);
}

}  // namespace rilo
