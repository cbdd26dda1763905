#pragma once
// A recording's ground-truth pose at any time inside it: position linearly,
// orientation by slerp, between neighbours no further apart than a gap (a
// hole in the ground truth is not bridged). For evaluation and import
// checks, never for the estimator.
#include <cstdint>
#include <vector>

#include "hal/recording/recording.h"
#include "math/types.h"

namespace rilo {

class TruthLookup {
 public:
  /// `truth` in time order; it must outlive the lookup.
  TruthLookup(const std::vector<GroundTruthPose>& truth, std::int64_t max_gap_ns)
      : truth_(truth), max_gap_ns_(max_gap_ns) {}
  TruthLookup(std::vector<GroundTruthPose>&&, std::int64_t) = delete;  ///< it keeps a reference

  /// The body pose at `t_ns`; false outside the ground truth or across a gap.
  bool at(std::int64_t t_ns, Mat3& R_w_b, Vec3& p_w_b) const;

 private:
  const std::vector<GroundTruthPose>& truth_;
  std::int64_t max_gap_ns_;
};

}  // namespace rilo
