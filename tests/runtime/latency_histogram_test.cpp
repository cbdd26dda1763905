// LatencyHistogram: percentiles within one bucket (~10 %) of the exact ones,
// never below them; bounded storage; no answer from no data.
#include "runtime/latency_histogram.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace rilo {
namespace {

double exactQuantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const auto rank = std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size()))));
  return v[rank - 1];
}

TEST(LatencyHistogram, EmptyGivesZeroAndCountsNothing) {
  LatencyHistogram h;
  EXPECT_EQ(h.count(), 0u);
  EXPECT_EQ(h.quantileMs(0.99), 0.0);
}

TEST(LatencyHistogram, QuantilesAreAtLeastTheExactOnesAndWithinOneBucket) {
  // Update times of a smoother: mostly ~0.3 ms, a tail to ~10 ms.
  std::mt19937 rng(7);
  std::lognormal_distribution<double> body(std::log(0.3), 0.5);
  std::uniform_real_distribution<double> tail(2.0, 10.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  LatencyHistogram h;
  std::vector<double> all;
  for (int i = 0; i < 20000; ++i) {
    const double ms = u(rng) < 0.02 ? tail(rng) : body(rng);
    h.add(ms);
    all.push_back(ms);
  }
  EXPECT_EQ(h.count(), all.size());
  const double bucket = std::pow(10.0, 1.0 / LatencyHistogram::kBucketsPerDecade);
  for (double q : {0.5, 0.9, 0.99, 0.999, 1.0}) {
    const double exact = exactQuantile(all, q);
    const double got = h.quantileMs(q);
    EXPECT_GE(got, exact) << "q " << q;
    EXPECT_LE(got, exact * bucket * (1.0 + 1e-12)) << "q " << q;
  }
}

TEST(LatencyHistogram, OutOfRangeValuesLandInTheEndBucketsAndNonDurationsAreIgnored) {
  LatencyHistogram h;
  h.add(0.0);
  h.add(1e-9);
  EXPECT_EQ(h.quantileMs(1.0), LatencyHistogram::upperEdgeMs(0));
  h.add(1e9);  // 11 days: the last bucket, not past the array
  EXPECT_EQ(h.quantileMs(1.0), LatencyHistogram::upperEdgeMs(LatencyHistogram::kBuckets - 1));
  h.add(-1.0);
  h.add(std::nan(""));
  EXPECT_EQ(h.count(), 3u);
}

}  // namespace
}  // namespace rilo
