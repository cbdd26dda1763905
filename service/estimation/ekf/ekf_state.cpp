#include "estimation/ekf/ekf_state.h"

namespace rilo {

EkfState EkfState::retract(const Vec15& dx) const {
  using namespace ekf_index;
  EkfState out;
  out.R_w_b = R_w_b * so3::exp(dx.segment<3>(kTheta));
  out.p_w_b = p_w_b + dx.segment<3>(kPos);
  out.v_w = v_w + dx.segment<3>(kVel);
  out.bias = ImuBias(bias.accel + dx.segment<3>(kAccelBias), bias.gyro + dx.segment<3>(kGyroBias));
  return out;
}

Vec15 EkfState::local(const EkfState& other) const {
  using namespace ekf_index;
  Vec15 dx;
  dx.segment<3>(kTheta) = so3::log(R_w_b.transpose() * other.R_w_b);
  dx.segment<3>(kPos) = other.p_w_b - p_w_b;
  dx.segment<3>(kVel) = other.v_w - v_w;
  dx.segment<3>(kAccelBias) = other.bias.accel - bias.accel;
  dx.segment<3>(kGyroBias) = other.bias.gyro - bias.gyro;
  return dx;
}

bool EkfState::allFinite() const {
  return R_w_b.allFinite() && p_w_b.allFinite() && v_w.allFinite() && bias.accel.allFinite() &&
         bias.gyro.allFinite();
}

}  // namespace rilo
