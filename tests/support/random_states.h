#pragma once
// Random states shared by the factor tests. Each helper draws from the caller's
// engine in a fixed order, so a given seed reproduces the same states in every test.
#include <random>

#include "math/pose3.h"
#include "math/types.h"

namespace rilo::testing {

/// Vector with i.i.d. N(0, scale^2) components.
inline Vec3 randomVec(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, scale);
  return Vec3(n(rng), n(rng), n(rng));
}

/// Uniformly random rotation (any magnitude, including near pi).
inline Mat3 randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Quat(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
}

/// Uniformly random rotation with a position of i.i.d. N(0, position_scale_m^2) components.
inline Pose3 randomPose(std::mt19937& rng, double position_scale_m) {
  return Pose3(randomRotation(rng), randomVec(rng, position_scale_m));
}

}  // namespace rilo::testing
