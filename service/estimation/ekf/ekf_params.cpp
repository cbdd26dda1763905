#include "estimation/ekf/ekf_params.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

[[noreturn]] void fail(const char* field, const char* rule, double value) {
  throw std::invalid_argument(std::string("EkfParams: ") + field + " must be " + rule + ", got " +
                              std::to_string(value));
}

}  // namespace

void EkfParams::validate() const {
  imu.validate();
  if (!(std::isfinite(max_imu_dt_s) && max_imu_dt_s > 0.0)) fail("max_imu_dt_s", "finite and > 0", max_imu_dt_s);
  if (!(gate_chi2_1dof > 0.0)) fail("gate_chi2_1dof", "> 0 (+inf: no gate)", gate_chi2_1dof);
  if (!(gate_chi2_2dof > 0.0)) fail("gate_chi2_2dof", "> 0 (+inf: no gate)", gate_chi2_2dof);
  if (!(tdoa_path_share >= 0.0 && tdoa_path_share < 1.0)) fail("tdoa_path_share", "in [0, 1)", tdoa_path_share);
  if (!(gate_group_scale > 0.0)) fail("gate_group_scale", "> 0 (+inf: no gate)", gate_group_scale);
  if (group_iterations < 1) fail("group_iterations", ">= 1", group_iterations);
  if (!(std::isfinite(velocity_noise_density) && velocity_noise_density >= 0.0)) {
    fail("velocity_noise_density", "finite and >= 0", velocity_noise_density);
  }
  if (!(recovery_gated_share > 0.0)) fail("recovery_gated_share", "> 0 (>= 1: off)", recovery_gated_share);
  if (!(std::isfinite(recovery_window_groups) && recovery_window_groups >= 1.0)) {
    fail("recovery_window_groups", "finite and >= 1", recovery_window_groups);
  }
  if (robust_iterations < 1) fail("robust_iterations", ">= 1", robust_iterations);
  if (!(min_robust_weight >= 0.0 && min_robust_weight < 1.0)) {
    fail("min_robust_weight", "in [0, 1)", min_robust_weight);
  }
}

}  // namespace rilo
