// The saturated scheme: one-point two-phase MPM with the semi-implicit
// fractional-step u–v–p integration of liang-zhao-wu-soga-2023 §2.2–3.
#ifndef RVEHUB_MPM_CLIENT_CORE_TWO_PHASE_SOLVER_H_
#define RVEHUB_MPM_CLIENT_CORE_TWO_PHASE_SOLVER_H_

#include <Eigen/Dense>
#include <cstdint>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "mpm_client/core/body_contact.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/solver.h"

namespace rvehub::mpm {

// One semi-implicit two-phase step over the shared state of Solver, with
// the water's own grid state: the effective stress explicit (from the
// model, as in the dry step), the Darcy drag and the pore pressure
// implicit, so that Δt depends neither on the permeability nor on the
// water's incompressibility. `points().mass` is the solids'. Made by
// Solver::ForCase for a saturated case.
class TwoPhaseSolver final : public Solver {
 public:
  absl::Status Step() override;

  // Solids' plus water's mass, kg.
  double MixtureMass() const override;
  // CG iterations of the last pressure solve, for diagnostics.
  int pressure_iterations() const { return pressure_iterations_; }
  // p^{n+1} of the last step per grid node, Pa; NaN where the node was
  // inactive. Part of the state: the next step's p^n where the node is
  // still active.
  const std::vector<double>& node_pressure() const { return node_pressure_last_; }
  // Sets it (a checkpoint's; one value per grid node).
  void set_node_pressure(std::vector<double> pressure) {
    node_pressure_last_ = std::move(pressure);
  }

 private:
  friend class Solver;  // its factory
  TwoPhaseSolver();

  // Drained boundaries, the bodies for the water, the porous nodes.
  absl::Status SetUpScheme(const CaseSpec& spec) override;
  // Porosity in (0, 1) and a finite pore pressure at every point.
  absl::Status ValidateInitialPoints(const MaterialPoints& points) const override;
  void Prepare() override;
  bool incremental() const { return phases_.projection == Projection::kIncremental; }

  // The stages of Step, in order.
  // The points' faces near a body (contacts_) hold the water out of it too:
  // fluid_contacts_, the mass floor scaled to the point's water.
  void FindFluidContacts();
  // (1) P2G of both phases (eqs. 29–30): m_s = the point's mass,
  // m_f = n ρ_f V, each node's share of soil Σ S V; p^n at the nodes.
  absl::Status MapToGrid();
  // FailedPrecondition for a point compacted below its solid volume (n ≤ 0).
  absl::Status CheckPorosity() const;
  // (3) The nodal forces (eqs. 16d–g): the mixture's, the fluid's and the
  // drag D = Δt Σ S·drag·V (eq. 16c, lumped).
  absl::Status ComputeNodalForces();
  // (4) The intermediate velocities v_s*, v_f* (eq. 15), drag implicit.
  void SolveIntermediateVelocities();
  // (5) The pressure Poisson equation (eq. 17) for δ = p^{n+1} − b.
  absl::Status SolvePressure();
  // (6) The velocity correction (eq. 19, lumped).
  void CorrectVelocities();
  // The walls' and bodies' constraints on both phases' new velocities, at
  // t + Δt.
  void ConstrainNewVelocities();
  // (7) G2P (eqs. 33–34), the pore pressure from the nodes' p^{n+1}.
  void MapToPoints();

  // Impermeable walls and bodies, the water's counterpart of Constrain: the
  // fluid's velocity normal to each wall's line is the wall's at wall_time
  // (0 unless shaken; fluid_fixed_ records the components held), except on
  // a drained boundary's nodes (a porous stone); the points' faces near a
  // body do not approach it, the water sliding freely (fluid_contacts_).
  // Adds weight × the fluid's momentum change to impulse_.
  void ConstrainFluid(std::vector<Eigen::Vector2d>& velocity, double wall_time, double weight);
  // A porous stone (a drained line on a wall's line): where the wall holds
  // the solids, the water's normal velocity in node_fluid_velocity_new_ is
  // solved again against solids held at the wall's velocity, not the free
  // mixture the 2×2 solve assumed: v_f = (M_f v0 + Δt F_f + D u)/(M_f + D),
  // v0 = start, u = pull (the held solids' velocity, or v0 itself where the
  // drag acts on the change only), D = node_drag_, F_f = node_fluid_force_.
  // The change counts in the wall's impulse.
  void DrainThroughWalls(const std::vector<Eigen::Vector2d>& start,
                         const std::vector<Eigen::Vector2d>& pull);
  // The pore pressure of the water at rest (hydrostatic below the water
  // table, 0 above it or without one) at height y and at a node, Pa.
  double RestPressure(double y) const;
  double NodeRest(int node) const;
  // The nodes whose pore pressure is prescribed this step (drained lines,
  // the free surface), into pressure_fixed_ (NaN: free).
  void FindDrainedNodes();
  // p^n at the active nodes that lack one (NaN in node_pressure_), fitted
  // to the points' pressures.
  absl::Status FitNodalPressure();

  std::vector<std::vector<std::int32_t>> drained_nodes_;   // per drained boundary
  std::vector<double> node_fluid_mass_;                    // kg
  std::vector<Eigen::Vector2d> node_fluid_velocity_;       // v_f^n, then v_f*, m/s
  std::vector<Eigen::Vector2d> node_fluid_force_;          // N
  std::vector<Eigen::Vector2d> node_fluid_velocity_new_;   // v_f^{n+1}
  std::vector<Eigen::Vector2d> node_fluid_velocity_star_;  // v_f* before the correction
  std::vector<double> node_drag_;                          // Δt·Σ S·drag·V, kg
  std::vector<double> node_pressure_;                      // p^n, Pa
  std::vector<double> node_pressure_last_;                 // see node_pressure()
  std::vector<double> pressure_fixed_;                     // prescribed p, Pa, or NaN
  std::vector<double> node_base_;          // b: p^n or p_r (two_phase_solver.cc), Pa
  std::vector<double> node_delta_;         // δ = p^{n+1} − b, Pa
  std::vector<double> node_volume_;        // Σ_p S_Ip V_p, m³
  std::vector<double> node_domain_;        // share of a node's volume inside walls and grid, [-]
  std::vector<double> node_soil_;          // soil share of a node's domain, [-], 0 where inactive
  std::vector<std::uint8_t> fluid_fixed_;  // per node: components walls hold
  // Per node: bit 0 / bit 1 set on a drained line x = c / y = c (a wall on
  // that line lets the water through there).
  std::vector<std::uint8_t> node_porous_;
  std::vector<RigidBody> fluid_bodies_;         // the bodies, smooth for the water
  std::vector<SurfaceContact> fluid_contacts_;  // contacts_ with the water's mass floor
  int pressure_iterations_ = 0;
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_TWO_PHASE_SOLVER_H_
