// The dry scheme: explicit MPM, update stress first (USF), as in Liang &
// Zhao's MPM×DEM §2.3 (the solution procedure, steps 2(a)–(d)).
#ifndef RVEHUB_MPM_CLIENT_CORE_EXPLICIT_SOLVER_H_
#define RVEHUB_MPM_CLIENT_CORE_EXPLICIT_SOLVER_H_

#include "absl/status/status.h"
#include "mpm_client/core/solver.h"

namespace rvehub::mpm {

// One explicit USF step over the shared state of Solver: the stress is
// updated from the velocities mapped at the step's start, before the nodal
// forces. Made by Solver::ForCase for a dry case.
class ExplicitSolver final : public Solver {
 public:
  absl::Status Step() override;

 private:
  friend class Solver;  // its factory
  ExplicitSolver();

  // (a) P2G: nodal mass (the inertia: point masses × the mass scale) and
  // momentum, then v^n = p/m on the active nodes.
  void MapToGrid();
  // (c) The nodal forces into node_force_: internal −Σ σ_p·∇S_Ip V_p
  // (eq. 12, the in-plane part of ForceStresses), gravity
  // Σ m_p g S_Ip = m_I g / scale (BodyAcceleration: on the real mass) and
  // the tractions (eq. 13); FailedPrecondition for a load without nodes.
  absl::Status ComputeNodalForces();
  // (c) v^{n+1} = v^n + Δt f/m on the active nodes (eq. 10), into
  // node_velocity_new_.
  void IntegrateNodalVelocities();
  // (d) G2P: v_p ← α v_PIC + (1 − α) v_FLIP (eqs. 17–19),
  // x_p ← x_p + Δt v_PIC (eq. 16), held off the walls.
  void MapToPoints();
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_EXPLICIT_SOLVER_H_
