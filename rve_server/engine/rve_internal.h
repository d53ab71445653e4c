// Private to the engine's .cc files (rve.cc, neighbour_list.cc,
// cell_flip.cc, step.cc, control.cc, homogenise.cc, packing.cc): small
// helpers they share, and Rve::ForEachContact, the one walk over the
// active contacts outside the step kernel.
#ifndef RVEHUB_RVE_SERVER_ENGINE_RVE_INTERNAL_H_
#define RVEHUB_RVE_SERVER_ENGINE_RVE_INTERNAL_H_

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <type_traits>
#include <utility>
#include <vector>

#include "rve_server/engine/contact_law.h"
#include "rve_server/engine/rve.h"

namespace rvehub::dem {
namespace internal {

constexpr double kPi = std::numbers::pi;

// Round to nearest (ties to even) by the 1.5·2^52 trick: two additions, no
// libm call, exact for |x| < 2^51. Used for the minimum image in reduced
// coordinates, which needs the cell to be reduced (MaybeFlip) and the cutoff
// below half of each cell height (CheckCellSize).
inline double RoundNearest(double x) {
  constexpr double kMagic = 6755399441055744.0;
  return (x + kMagic) - kMagic;  // not folded to x: no -ffast-math (see CMakeLists)
}

// sign(x) ∈ {−1, 0, 1}.
inline double Sign(double x) { return (x > 0.0) - (x < 0.0); }

// Local non-viscous damping force −α|f|·sign(v) (N), one component; −0 for
// v = 0. Selects rather than multiplies by sign(v), so the compiler can blend
// it in SIMD lanes (sign(v) is unpredictable: no branch either way).
inline double Damping(double alpha, double f, double v) {
  const double d = alpha * std::abs(f);
  return v > 0.0 ? -d : (v < 0.0 ? d : -0.0);
}

// Heights of the cell (m): distance between the two pairs of opposite edges.
inline Eigen::Vector2d CellHeights(const Eigen::Matrix2d& h) {
  const double area = std::abs(h.determinant());
  return {area / h.col(1).norm(), area / h.col(0).norm()};
}

// Singular values (min, max) of a 2×2 matrix, closed form.
inline std::pair<double, double> SingularValues(const Eigen::Matrix2d& m) {
  const double a = m.squaredNorm();
  const double det = std::abs(m.determinant());
  const double root = std::sqrt(std::max(a * a - 4.0 * det * det, 0.0));
  return {std::sqrt(std::max((a - root) / 2.0, 0.0)), std::sqrt((a + root) / 2.0)};
}

inline Eigen::Matrix2d Rotation(double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

// Scratch shared by every RVE on a thread (keeps RVEs small): the contact
// pass's per-pair results and per-particle contact counts, Observe's
// per-particle terms.
struct Scratch {
  std::vector<std::int32_t> count;  // contacts per particle
  // Per listed pair, from the pair pass: force on i (N), torques on i and j
  // (N·m); while measuring, the six terms of the measured sums (see
  // PairPass), the elastic energy (J) and 1 for an active contact (else all 0).
  std::vector<double> fx, fy, ti, tj, elastic, active;
  std::array<std::vector<double>, 6> term;
  // Per particle, for Observe: |Σ contact forces| (N), m v² + I ω² (J).
  std::vector<double> resultant, kinetic2;
};
inline Scratch& ThreadScratch() {
  thread_local Scratch scratch;
  return scratch;
}

// Cells of the neighbour search's grid for a cell of heights `heights` (m)
// and a pair cutoff (m); as a double, so that a huge cell cannot overflow.
inline double GridCells(const Eigen::Vector2d& heights, double cutoff) {
  return std::floor(heights.x() / cutoff) * std::floor(heights.y() / cutoff);
}

// The most grid cells a packing of n particles may need.
inline double MaxGridCells(std::size_t n) {
  return std::max(kMinGridCells, kMaxGridCellsPerParticle * static_cast<double>(n));
}

}  // namespace internal

template <typename F>
void Rve::ForEachContact(F&& f) const {
  const std::size_t n = p_.radius.size();
  const Material& mat = p_.material;
  const bool bonds = !nbr_bond_.empty();
  ContactForce c;
  for (std::uint32_t i = 0; i < n; ++i) {
    for (std::uint32_t k = row_start_[i]; k < row_start_[i + 1]; ++k) {
      const std::uint32_t j = nbr_j_[k];
      c.branch = Branch(i, j);
      const double rsum = p_.radius[i] + p_.radius[j];
      c.bonded = bonds && nbr_bond_[k] > 0;
      const double dist = c.branch.norm();
      if (dist >= rsum && !c.bonded) continue;
      c.i = i;
      c.j = j;
      c.normal = c.branch / dist;
      c.overlap = rsum - dist;
      const NormalResponse law = NormalLaw(mat, p_.radius[i], p_.radius[j], c.overlap);
      c.normal_force = law.fn;
      c.kn = law.kn;
      c.kt = law.kt;
      c.tangential_force = nbr_ft_[k];
      if constexpr (std::is_invocable_v<F, const ContactForce&, std::uint32_t>) {
        f(c, k);
      } else {
        f(c);
      }
    }
  }
}

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_ENGINE_RVE_INTERNAL_H_
