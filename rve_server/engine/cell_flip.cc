// Cell flips (an exact change of lattice basis that keeps a sheared cell
// reduced) and rigid rotations of the whole RVE.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "rve_server/engine/rve.h"
#include "rve_server/engine/rve_internal.h"

namespace rvehub::dem {

using internal::Rotation;

// Keeps the cell reduced (|a·b| ≤ ½|a|², ½|b|²) by an exact change of
// lattice basis, so shear can go on without limit.
void Rve::MaybeFlip() {
  const Eigen::Vector2d a = p_.cell.col(0), b = p_.cell.col(1);
  const double ab = a.dot(b);
  int kb = 0, ka = 0;
  if (std::abs(ab) > 0.55 * a.squaredNorm())
    kb = static_cast<int>(std::lround(ab / a.squaredNorm()));
  else if (std::abs(ab) > 0.55 * b.squaredNorm())
    ka = static_cast<int>(std::lround(ab / b.squaredNorm()));
  if (kb == 0 && ka == 0) return;
  const std::size_t n = p_.radius.size();
  if (kb != 0) {  // b' = b − kb·a; s'_x = s_x + kb·s_y
    p_.cell.col(1) = b - kb * a;
    p_.reference_cell.col(1) -= kb * p_.reference_cell.col(0);
    for (std::size_t i = 0; i < n; ++i) p_.sx[i] += kb * p_.sy[i];
  } else {  // a' = a − ka·b; s'_y = s_y + ka·s_x
    p_.cell.col(0) = a - ka * b;
    p_.reference_cell.col(0) -= ka * p_.reference_cell.col(1);
    for (std::size_t i = 0; i < n; ++i) p_.sy[i] += ka * p_.sx[i];
  }
  for (std::size_t i = 0; i < n; ++i) {
    p_.sx[i] -= std::floor(p_.sx[i]);
    p_.sy[i] -= std::floor(p_.sy[i]);
  }
  Rebuild(CollectHistory());
}

void Rve::ApplyRigidRotation(double angle) {
  if (angle == 0.0) return;
  const Eigen::Matrix2d r = Rotation(angle);
  // The contact forces turn with the packing (the next step integrates
  // with them); the homogenised sums are measured again by that step.
  sums_valid_ = false;
  if (forces_valid_) {
    for (std::size_t i = 0; i < fx_.size(); ++i) {
      const double fx = fx_[i], fy = fy_[i];
      fx_[i] = r(0, 0) * fx + r(0, 1) * fy;
      fy_[i] = r(1, 0) * fx + r(1, 1) * fy;
    }
  }
  p_.cell = r * p_.cell;
  p_.frame = r * p_.frame;
  cell_at_build_ = r * cell_at_build_;
  for (std::size_t i = 0; i < p_.radius.size(); ++i) {
    const double vx = p_.vx[i], vy = p_.vy[i];
    p_.vx[i] = r(0, 0) * vx + r(0, 1) * vy;
    p_.vy[i] = r(1, 0) * vx + r(1, 1) * vy;
    p_.theta[i] += angle;
  }
}

}  // namespace rvehub::dem
