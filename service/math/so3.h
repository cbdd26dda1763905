#pragma once
// SO(3) exponential/logarithm and their Jacobians (right-perturbation
// convention: R (+) phi = R * Exp(phi)), as in Forster et al. (TRO 2017).
#include "math/types.h"

namespace rilo::so3 {

/// Skew-symmetric matrix: hat(a) * b == a.cross(b).
Mat3 hat(const Vec3& a);

/// Exp: rotation vector (rad) -> rotation matrix (Rodrigues; Taylor series near 0).
Mat3 exp(const Vec3& phi);

/// Log: rotation matrix -> rotation vector (rad), |phi| <= pi; accurate near 0 and pi.
Vec3 log(const Mat3& R);

/// Right Jacobian Jr(phi): Exp(phi + d) ~= Exp(phi) Exp(Jr(phi) d).
Mat3 rightJacobian(const Vec3& phi);

/// Inverse right Jacobian: Log(Exp(phi) Exp(d)) ~= phi + Jr^-1(phi) d.
Mat3 rightJacobianInverse(const Vec3& phi);

/// Projects a nearly orthonormal matrix back onto SO(3) (via quaternion).
Mat3 normalize(const Mat3& R);

}  // namespace rilo::so3
