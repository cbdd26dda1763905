#pragma once
// Absolute position error statistics (no alignment: the anchors fix the frame),
// split into 3D, horizontal and vertical as the architecture asks.
#include <vector>

#include "math/types.h"

namespace rilo {

struct ErrorStats {
  double mean = 0.0, median = 0.0, rmse = 0.0, max = 0.0;
  std::size_t count = 0;
};

struct PositionErrorStats {
  ErrorStats ape_3d;          ///< |p_est - p_true| (m)
  ErrorStats ape_horizontal;  ///< |(p_est - p_true)_xy| (m)
  ErrorStats ape_vertical;    ///< |(p_est - p_true)_z| (m)
  /// Mean of (p_est - p_true)_z (m; 0 without pairs): the signed height
  /// offset. With anchors at similar heights a common NLOS excess moves the
  /// tag vertically (docs/noise-models.md, "What bounds the height"); a
  /// vertical mean error that equals |bias| is an offset, not noise.
  double vertical_bias_m = 0.0;
};

ErrorStats errorStats(std::vector<double> errors);
/// Element-wise statistics; throws std::invalid_argument on size mismatch.
PositionErrorStats positionErrorStats(const std::vector<Vec3>& p_est, const std::vector<Vec3>& p_true);

}  // namespace rilo
