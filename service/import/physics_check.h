#pragma once
// Checks a recording's units and TDoA sign against its own ground truth, so an
// importer can tell a wrong assumption from the data (docs/util-dataset.md):
//  - accelerometer: median |a| over all samples against gravity;
//  - gyroscope: the integral of the rate over short windows against the
//    ground-truth rotation over the same windows (least-squares scale);
//  - TDoA: residuals diff - (|p - A_b| - |p - A_a|) at the interpolated
//    ground-truth antenna position, with the stored sign and flipped; then a
//    fit of a lever-arm correction plus one constant bias per anchor pair.
// Figures only; what they mean for the options is the importer's business.
// Not for the real-time path (allocates, dynamic-size solve).
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "hal/recording/recording.h"
#include "math/types.h"

namespace rilo::importer {

struct PhysicsCheckParams {
  double gyro_window_s = 0.25;            ///< length of the rotation windows (s)
  double min_window_rotation_rad = 0.03;  ///< windows with less ground-truth rotation are not used
  double max_window_rotation_rad = 2.0;   ///< nor with more (Log wraps at pi)
  double max_imu_gap_s = 0.05;            ///< a window with a larger IMU gap is not used
  double max_truth_gap_s = 0.1;           ///< no ground truth interpolated across a larger gap
  double fit_gate_m = 1.0;                ///< first-pass gate of the lever-arm/bias fit (|residual|)
  std::size_t min_pair_samples = 10;      ///< pairs with fewer gated samples stay out of the fit
  double lever_arm_evident_m = 0.02;      ///< a lever-arm component is evident above this and 3 sigma
  double bias_evident_m = 0.05;           ///< a pair bias is evident above this and 3 sigma
};

struct AccelCheck {
  std::size_t samples = 0;
  double median_norm_m_s2 = std::numeric_limits<double>::quiet_NaN();
  double ratio_to_gravity = std::numeric_limits<double>::quiet_NaN();  ///< median |a| / g
};

struct GyroCheck {
  std::size_t windows = 0;             ///< windows used
  double total_rotation_rad = 0.0;     ///< sum of the ground-truth rotation angles of the windows used
  double scale = std::numeric_limits<double>::quiet_NaN();  ///< least squares: truth rotation = scale * gyro integral
  double relative_residual = std::numeric_limits<double>::quiet_NaN();  ///< |truth - scale*gyro| / |truth| (RMS over windows)
};

struct PairBias {
  std::uint32_t anchor_a = 0;
  std::uint32_t anchor_b = 0;
  std::size_t samples = 0;   ///< samples in the fit
  double bias_m = 0.0;       ///< constant part of diff - predicted (m)
  double sigma_m = 0.0;      ///< its standard deviation from the fit (m)
  bool evident = false;
};

struct TdoaCheck {
  std::size_t samples = 0;  ///< TDoA samples with ground truth
  double median_abs_residual_m = std::numeric_limits<double>::quiet_NaN();          ///< stored sign
  double median_abs_residual_flipped_m = std::numeric_limits<double>::quiet_NaN();  ///< diff negated
  double median_residual_m = std::numeric_limits<double>::quiet_NaN();              ///< signed, stored sign
  bool fit_ok = false;                 ///< the lever-arm/bias fit was solvable
  std::size_t fit_samples = 0;
  double fit_sigma_m = 0.0;            ///< residual standard deviation after the fit (m)
  Vec3 lever_arm_correction_m = Vec3::Zero();  ///< add to the lever arm, body frame (m)
  Vec3 lever_arm_sigma_m = Vec3::Zero();
  bool lever_arm_evident = false;
  std::vector<PairBias> pair_biases;   ///< every fitted pair, largest |bias| first
};

struct PhysicsCheck {
  AccelCheck accel;
  GyroCheck gyro;
  TdoaCheck tdoa;
};

/// Runs the three checks on `rec` (imu, tdoa, groundtruth, anchors; the UWB
/// antenna at meta.uwb_lever_arm_m, gravity meta.gravity_m_s2). Parts without
/// the data they need are left at their defaults (0 samples, NaN figures).
PhysicsCheck checkPhysics(const Recording& rec, const PhysicsCheckParams& params = {});

}  // namespace rilo::importer
