#pragma once
// Random numbers for the office simulator: portable and reproducible.
//
// std::mt19937_64 is fully specified by the standard, but the std::
// distributions are not (libstdc++ and libc++ give different normals for the
// same engine), so the uniform and normal draws are our own: the same seed
// gives the same draws with every standard library. Every part of the simulation
// draws from its own stream (plan, walk, IMU, ranging, channel fields), so
// changing one part does not reshuffle the others.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Core>

namespace rilo::sim {

/// SplitMix64 finalizer: decorrelates nearby seeds.
inline std::uint64_t mixSeed(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Seed of stream `stream` of the simulation seeded with `seed`.
inline std::uint64_t streamSeed(std::uint64_t seed, std::uint64_t stream) {
  return mixSeed(mixSeed(seed) ^ mixSeed(stream + 0x51ed270b27a5f3c1ULL));
}

class SimRng {
 public:
  explicit SimRng(std::uint64_t seed) : engine_(seed) {}

  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Uniform integer in [0, n), n > 0.
  std::size_t index(std::size_t n) { return static_cast<std::size_t>(uniform() * static_cast<double>(n)) % n; }
  bool bernoulli(double p) { return uniform() < p; }

  /// Standard normal (Marsaglia polar method, the spare value kept).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u = 0.0, v = 0.0, s = 0.0;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double f = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * f;
    has_spare_ = true;
    return u * f;
  }
  Eigen::Vector3d normal3() {
    const double x = normal();
    const double y = normal();
    const double z = normal();
    return {x, y, z};
  }

  /// |scale * tan(pi/2 * U)|: half-Cauchy with median `scale`.
  double halfCauchy(double scale) { return scale * std::tan(0.5 * std::numbers::pi * uniform()); }

  /// Fisher-Yates shuffle.
  template <typename T>
  void shuffle(std::vector<T>& v) {
    for (std::size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[index(i)]);
  }

 private:
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// A smooth random field over space, zero mean and unit variance, with a
/// Gaussian correlation exp(-|d|^2 / (2 L^2)) (random Fourier features:
/// sqrt(2/M) sum cos(k_m . p + phase_m), k_m ~ N(0, I / L^2)). Nearly Gaussian
/// for M >= 16. Used for quantities that follow geometry: the NLOS excess and
/// the shadowing of one link change as the tag moves, not from range to range.
class SmoothField {
 public:
  SmoothField() = default;
  SmoothField(SimRng& rng, double length_m, int terms = 16) {
    k_.reserve(static_cast<std::size_t>(terms));
    phase_.reserve(static_cast<std::size_t>(terms));
    for (int m = 0; m < terms; ++m) {
      k_.push_back(rng.normal3() / length_m);
      phase_.push_back(2.0 * std::numbers::pi * rng.uniform());
    }
    gain_ = std::sqrt(2.0 / static_cast<double>(terms));
  }
  double operator()(const Eigen::Vector3d& p) const {
    double sum = 0.0;
    for (std::size_t m = 0; m < k_.size(); ++m) sum += std::cos(k_[m].dot(p) + phase_[m]);
    return gain_ * sum;
  }

 private:
  std::vector<Eigen::Vector3d> k_;
  std::vector<double> phase_;
  double gain_ = 0.0;
};

/// Standard normal CDF.
inline double normalCdf(double x) { return 0.5 * std::erfc(-x / std::numbers::sqrt2); }

}  // namespace rilo::sim
