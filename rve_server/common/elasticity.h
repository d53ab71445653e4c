// Small-strain isotropic elasticity and the polar rotation of an in-plane
// deformation gradient: the formulas the continuum clients' stand-in
// materials share (one place for each).
#ifndef RVEHUB_RVE_SERVER_COMMON_ELASTICITY_H_
#define RVEHUB_RVE_SERVER_COMMON_ELASTICITY_H_

#include <Eigen/Dense>
#include <cmath>

namespace rvehub {

// R of the polar decomposition F = R·U of an in-plane F with det F > 0.
inline Eigen::Matrix2d PolarRotation(const Eigen::Matrix2d& f) {
  // For F = R(θ)·U with U symmetric positive definite: F10 − F01 = sin θ·tr U
  // and F00 + F11 = cos θ·tr U.
  const double theta = std::atan2(f(1, 0) - f(0, 1), f(0, 0) + f(1, 1));
  const double c = std::cos(theta), s = std::sin(theta);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

// P-wave (constrained) modulus M = E(1 − ν)/((1 + ν)(1 − 2ν)), Pa.
inline double PWaveModulus(double youngs, double poisson) {
  return youngs * (1.0 - poisson) / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
}

// Lamé's λ = Eν/((1 + ν)(1 − 2ν)) and the shear modulus G = E/(2(1 + ν)), Pa.
inline double LameLambda(double youngs, double poisson) {
  return youngs * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
}
inline double ShearModulus(double youngs, double poisson) {
  return youngs / (2.0 * (1.0 + poisson));
}

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_COMMON_ELASTICITY_H_
