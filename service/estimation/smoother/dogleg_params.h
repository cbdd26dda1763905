#pragma once
// RISE's step policy (incremental Powell's dog-leg, the Ranging-IMU Fusion paper's third
// smoother): its trust region. The step itself is dogleg_step.cpp.
#include <stdexcept>
#include <string>

namespace rilo {

struct DoglegParams {
  double trust_radius_initial = 0.1;  ///< Ranging-IMU Fusion paper: initial delta 0.1
  double trust_radius_min = 1e-8;     ///< stop shrinking (keep the linearization point) below this

  /// Throws std::invalid_argument naming the first bad field
  /// ("SmootherParams.dogleg.<field> ...").
  void validate() const {
    auto fail = [](const char* field, const char* rule) {
      throw std::invalid_argument(std::string("SmootherParams.dogleg.") + field + " " + rule);
    };
    if (!(trust_radius_initial > 0.0)) fail("trust_radius_initial", "must be > 0");
    if (!(trust_radius_min > 0.0 && trust_radius_min <= trust_radius_initial)) fail("trust_radius_min", "must be in (0, trust_radius_initial]");
  }
};

}  // namespace rilo
