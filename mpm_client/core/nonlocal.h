// Nonlocal averaging over material points: the internal length a softening
// continuum lacks. Pure (Eigen only), stateless apart from the map it builds.
#ifndef RVEHUB_MPM_CLIENT_CORE_NONLOCAL_H_
#define RVEHUB_MPM_CLIENT_CORE_NONLOCAL_H_

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

namespace rvehub::mpm {

// The bell weight of a neighbour at distance r (m) for the radius ℓ (m):
// (1 − r²/ℓ²)² for r < ℓ, else 0, [-].
double NonlocalWeight(double r, double radius);

// The symmetric nonlocal average of Borino, Failla & Parrinello (2003) over
// material points at positions x (m) with volumes V (m³):
//   ā_p = a_p + Σ_{q≠p} c_pq (a_q − a_p),  c_pq = w(|x_p − x_q|) V_q / S∞,
// S∞ = max(π ℓ² t / 3, max_p Σ_q w_pq V_q) (the full plane's ∫ w dA times the
// thickness t, m³). In the interior it is the weighted mean over the disc of
// radius ℓ; where a point lacks neighbours (a free surface, a body) the
// missing share stays its own. It keeps constants bit for bit, and V_p c_pq
// is symmetric, so the map is self-adjoint in the volume-weighted sum:
// Σ V_p b_p ā_p = Σ V_p a_p b̄_p. A strain averaged by it and a stress averaged
// by it in the internal forces therefore do the same work.
// With a fraction m < 1 every c_pq is scaled by m: ā = (1 − m) a + m·(the
// full average). The full average nearly annuls a field that alternates
// from point to point (one point per cell, ℓ = 2h: −0.06 of it), and a
// strain the map annuls meets no stiffness; the blend keeps at least about
// 1 − 1.06 m of it.
class NonlocalMap {
 public:
  // Points with active[p] == 0 (parked off the grid) neither take part nor
  // change. The pairs are found by sorting the points into square bins of
  // side ℓ; each point's sum runs over its neighbours in a fixed order, so
  // the result depends on the positions only (not on threads).
  static NonlocalMap Build(std::span<const Eigen::Vector2d> position,
                           std::span<const double> volume, std::span<const std::uint8_t> active,
                           double radius, double thickness, double fraction);

  // out[p] = ā_p for one scalar per point; out must not alias in.
  void Apply(std::span<const double> in, std::span<double> out) const;

  std::size_t size() const { return start_.empty() ? 0 : start_.size() - 1; }
  // Neighbours of p (itself excluded) and their coefficients c_pq.
  std::span<const std::int32_t> Neighbours(std::size_t p) const;
  std::span<const double> Coefficients(std::size_t p) const;

 private:
  std::vector<std::int64_t> start_;      // per point, into the two arrays below
  std::vector<std::int32_t> neighbour_;  // q
  std::vector<double> coefficient_;      // c_pq, [-]
};

// Nonlocal strain (SolverSpec::nonlocal_radius): the symmetric part of each
// in-plane increment, sym(ΔF_p − I), replaced by its average, the point's own
// rotation kept. A homogeneous increment is unchanged bit for bit. [-]
void AverageStrainIncrement(const NonlocalMap& map, std::span<Eigen::Matrix2d> df);

// The in-plane stresses (Pa) averaged by the same map, for the internal
// forces: with AverageStrainIncrement's strains, Σ V σ̄:ε = Σ V σ:ε̄.
std::vector<Eigen::Matrix2d> AverageInPlaneStress(const NonlocalMap& map,
                                                  std::span<const Eigen::Matrix3d> stress);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_NONLOCAL_H_
