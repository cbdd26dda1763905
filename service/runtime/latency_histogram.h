#pragma once
// Fixed log-spaced histogram of durations (ms) for a running service's
// percentiles: 24 buckets per decade from 1 us to 100 s, so a percentile is
// known within one bucket (a factor 10^(1/24), ~10 %). Storage is a fixed
// array: add() never allocates and memory stays bounded over any run.
// Not thread-safe: one writer, readers under the writer's lock.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace rilo {

class LatencyHistogram {
 public:
  static constexpr int kBucketsPerDecade = 24;
  static constexpr double kMinMs = 1e-3;  ///< first bucket's lower edge
  static constexpr int kDecades = 8;      ///< up to kMinMs * 1e8 = 100 s; longer ones land in the last bucket
  static constexpr int kBuckets = kBucketsPerDecade * kDecades;

  void add(double ms) noexcept {
    if (!(ms >= 0.0)) return;  // NaN or negative: not a duration
    ++counts_[static_cast<std::size_t>(bucketOf(ms))];
    ++count_;
  }

  std::uint64_t count() const noexcept { return count_; }

  /// Upper edge of the bucket holding the q-quantile (q in [0, 1]): at least
  /// the true quantile and at most ~10 % above it. 0 when nothing was added.
  double quantileMs(double q) const noexcept {
    if (count_ == 0) return 0.0;
    q = std::clamp(q, 0.0, 1.0);
    // The smallest bucket whose cumulative count reaches ceil(q * n) (at least 1).
    const auto rank = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(count_))));
    std::uint64_t seen = 0;
    for (int b = 0; b < kBuckets; ++b) {
      seen += counts_[static_cast<std::size_t>(b)];
      if (seen >= rank) return upperEdgeMs(b);
    }
    return upperEdgeMs(kBuckets - 1);
  }

  static double upperEdgeMs(int bucket) noexcept {
    return kMinMs * std::pow(10.0, static_cast<double>(bucket + 1) / kBucketsPerDecade);
  }

 private:
  static int bucketOf(double ms) noexcept {
    if (ms <= kMinMs) return 0;
    const double b = std::floor(std::log10(ms / kMinMs) * kBucketsPerDecade);
    return static_cast<int>(std::clamp(b, 0.0, static_cast<double>(kBuckets - 1)));
  }

  std::array<std::uint64_t, kBuckets> counts_{};
  std::uint64_t count_ = 0;
};

}  // namespace rilo
