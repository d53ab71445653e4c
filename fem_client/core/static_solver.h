// The implicit quasi-static FEM solver of the FEM×DEM scheme (Guo & Zhao
// 2014, §2.3): load steps, each solved by Newton–Raphson iterations whose
// stresses and tangents come from a GaussPointMaterial (the RVEs, or a
// stand-in), updated Lagrangian (assembly.h). Plane strain, SI units,
// forces per metre of thickness. Single-threaded and deterministic.
#ifndef RVEHUB_FEM_CLIENT_CORE_STATIC_SOLVER_H_
#define RVEHUB_FEM_CLIENT_CORE_STATIC_SOLVER_H_

#include <Eigen/Dense>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "fem_client/core/assembly.h"
#include "fem_client/core/boundary.h"
#include "fem_client/core/material.h"
#include "fem_client/core/mesh.h"
#include "fem_client/core/second_gradient.h"
#include "fem_client/core/tangent_operator.h"

namespace rvehub::fem {

// Where a load step's Newton iterations start.
enum class Predictor {
  // From Δu = 0 on the committed state, the prescribed increments imposed
  // through the first solve (G&Z §2.3).
  kZero,
  // From the last converged sub-step's increment scaled to this one (a
  // secant extrapolation, one Trial): on a smooth path it starts Newton
  // near the solution, so fewer iterations reach the tolerance. A predictor
  // whose Trial fails falls back to kZero's start.
  kPrevious,
};

struct SolverOptions {
  TangentOperator tangent = TangentOperator::kContact;
  Predictor predictor = Predictor::kZero;
  // Converged when E_d = ‖Δu^j − Δu^{j−1}‖₂/‖Δu^j‖₂ < this (G&Z eq. 21;
  // their 0.01), over all dofs.
  double displacement_tolerance = 0.01;
  // When > 0, E_f = ‖R^j‖₂/‖f‖₂ < this is also required (0: E_f is only
  // reported, as in G&Z).
  double force_tolerance = 0.0;
  int max_iterations = 25;  // per (sub-)step, [1, 1000]
  int max_cutbacks = 6;     // halvings of one load step, [0, 30]
  // A sub-step whose iterations run out: false, it is cut back (and the
  // step fails once the cut-backs run out); true, its last iterate is
  // committed as it stands and the step goes on (Desrues et al.'s
  // "non-converged steps": past a snap-back no equilibrium is near, and
  // smaller parts do not help). Failures that leave no iterate (a failed
  // Trial, a singular stiffness) are cut back either way.
  bool accept_unconverged = false;
  double perturbation = 5e-5;  // ξ of kPerturbation (G&Z §3.3), (0, 0.1)
  // D of the local second gradient (second_gradient.h), N; 0: none. When
  // > 0 every element must be Q8R, and E_d stays over the displacements.
  double second_gradient = 0.0;
};

// One Newton iteration: a solve, then the Trial of the new Δu^j.
struct IterationReport {
  double displacement_error = 0.0;  // E_d
  // E_f = ‖R^j‖₂/‖f‖₂ over the unknowns, with f the external forces
  // (pressures, forced platens' loads) plus the reactions of the prescribed
  // dofs (f_int there): 0 when R^j = 0, infinite when R^j ≠ 0 but f = 0.
  double force_error = 0.0;
};

struct SubStepReport {
  double fraction = 1.0;  // of the load step: 1, or 1/2^k after k cut-backs
  std::vector<IterationReport> iterations;
  bool converged = true;  // false: accepted unconverged (accept_unconverged)
};

// The nodal forces on a node set at the end of a step, N/m.
struct SetForces {
  Eigen::Vector2d reaction = Eigen::Vector2d::Zero();  // Σ (f_int − f_ext): by the supports
  Eigen::Vector2d internal = Eigen::Vector2d::Zero();  // Σ f_int: the body's on the set
};

// A forced platen (Boundary::forced) after a step.
struct PlatenState {
  double force = 0.0;  // the load: the sum of the increments applied so far, N/m
  // What resists it: Σ (f_int − the other external forces, e.g. pressures
  // on its nodes) along its dof over all that moves with it (its nodes,
  // periodic slaves that follow them); the load to the convergence
  // tolerance (E_d alone may leave a residual force), N/m.
  double resistance = 0.0;
  double displacement = 0.0;  // its master's along its dof since Create, m
};

struct StepReport {
  int step = 0;                         // 1-based
  int cutbacks = 0;                     // halvings this step needed
  int trials = 0;                       // Trial calls, failed attempts and perturbations included
  std::vector<SubStepReport> substeps;  // the converged ones, in order
  std::map<std::string, SetForces> forces;  // per node set of the mesh
  std::vector<PlatenState> platens;         // per forced platen, in Boundary::forced order
};

// What a checkpoint holds of a solver to go on exactly where it was: the
// committed configuration and the last converged Trial on it (where the
// next step starts). The rest (the Gauss points' geometry, the node sets'
// forces, the forced platens' states) follows from these bit for bit.
struct SolverState {
  int steps = 0;                         // load steps done
  std::vector<Eigen::Vector2d> nodes;    // committed node positions, m
  Eigen::VectorXd displacement;          // since Create, 2 per node, m
  std::vector<PointResponse> responses;  // of the last committed Trial; empty before the first step
  Eigen::VectorXd f_int, f_ext, residual;  // of that Trial, all dofs, N/m
  std::vector<double> platen_force;        // each forced platen's load there, N/m
  std::vector<Tangent> initial_tangents;   // kInitialElastic's, once known
  // kPrevious's: the last converged sub-step's increment of the unknowns
  // (the displacements', then the second gradient's) per unit of load-step
  // factor; empty before the first.
  Eigen::VectorXd last_rate;
  // The second gradient's committed fields; empty without one.
  SecondGradientState second_gradient;
};

class StaticSolver {
 public:
  // Checks the mesh (ValidateMesh), the boundary (DofMap::Create), the
  // supports (CheckSupports: FailedPrecondition "the mesh has no supports
  // ...") and the options (InvalidArgument). `material` (not owned) has one
  // point per Gauss point of the mesh, in mesh order, and must outlive the
  // solver.
  static absl::StatusOr<std::unique_ptr<StaticSolver>> Create(Mesh mesh, Boundary boundary,
                                                              SolverOptions options,
                                                              GaussPointMaterial* material);

  // One load step: the prescribed increments, the periodic offset increment
  // and the forced platens' force increments times `factor` (e.g. −1 to
  // reverse a cycle; a cut-back part of the step applies its part of each).
  // The first step starts with a Trial of every point at ΔF = I (iteration
  // 0: the initial stresses, and kInitialElastic's tangents). Each step
  // starts from Δu⁰ = 0 on the committed state: the first solve uses its
  // tangent and residual with the increments imposed (E_d = 1 then, so at
  // least two iterations), each later one the last Trial's. A sub-step that
  // does not converge in max_iterations, whose Trial fails, or whose
  // iterate inverts an element or meets a singular tangent is halved, at
  // most max_cutbacks times; a converged sub-step is committed and the rest
  // of the step goes on at that size. Errors start "load step N (a part of
  // f of it, after k cut-backs), iteration j: " and name the worst point: a
  // Trial's own status (code, message and PointFailure kept) naming the
  // failing Gauss point; Aborted for no convergence (naming the node with
  // the largest residual), an inverted element or a singular tangent;
  // FailedPrecondition when the material gives no tangent the operator
  // needs. After an error the solver keeps its last committed state.
  absl::StatusOr<StepReport> Step(double factor = 1.0);

  // The committed configuration: node positions after the last step.
  const Mesh& mesh() const { return mesh_; }
  // Total displacement since Create, 2 per node, m.
  const Eigen::VectorXd& displacement() const { return displacement_; }
  // The forced platens after the last step (force 0 before the first).
  std::span<const PlatenState> platens() const { return platens_; }
  // The responses of the last committed Trial (empty before the first step).
  std::span<const PointResponse> responses() const { return committed_.responses; }
  int steps() const { return steps_; }

  // The state to go on from (SolverState), and back into a solver created
  // for the same mesh, boundary and options. Restore refuses
  // (InvalidArgument naming the field) a state whose arrays do not fit the
  // mesh or whose values are not finite, or one that inverts an element;
  // a refused state changes nothing.
  SolverState State() const;
  absl::Status Restore(SolverState state);

 private:
  // A Trial of every Gauss point at Δu and what follows from it.
  struct Evaluation {
    std::vector<Eigen::Vector2d> x;      // node positions X + Δu, m
    std::vector<PointGeometry> current;  // the Gauss points on x
    std::vector<Eigen::Matrix3d> delta_f;
    std::vector<PointResponse> responses;
    // f_int includes the second gradient's λ share (`multiplier_forces`).
    Eigen::VectorXd f_int, f_ext, residual;  // all dofs, N/m
    std::vector<double> platen_force;        // each forced platen's load, N/m
    // With a second gradient: λ's nodal forces, its own residual and the
    // double stresses (SecondGradient::Terms).
    Eigen::VectorXd multiplier_forces, sg_residual;
    std::vector<DoubleStress> double_stress;
  };
  struct Failure;

  StaticSolver(Mesh mesh, Boundary boundary, SolverOptions options, GaussPointMaterial* material,
               DofMap dofs, std::vector<PointGeometry> reference,
               std::optional<SecondGradient> second_gradient);

  // One attempt at `factor` of the step's increments: Newton to
  // convergence (or, with accept_unconverged, to the last iteration) and
  // Commit (true), or a Failure.
  bool TrySubStep(double factor, SubStepReport& report, Failure& failure);
  // Commits the RVEs at `ev` (the last Trial, of Δu = du and the second
  // gradient's ds; q: du's unknowns) and makes it the configuration the
  // next sub-step starts from.
  bool CommitIterate(double factor, const Eigen::VectorXd& du, const Eigen::VectorXd& q,
                     const Eigen::VectorXd& ds, Evaluation& ev, Failure& failure);
  // Trial and residual at Δu = du (and the second gradient's increments
  // ds), the forced platens loaded by `platen_force` (N/m each).
  bool Evaluate(const Eigen::VectorXd& du, const Eigen::VectorXd& ds, int iteration,
                std::span<const double> platen_force, Evaluation& ev, Failure& failure);
  // The second gradient's terms at zero increments on the committed
  // configuration into committed_ (where the next step starts); with
  // `move_forces`, λ's share of f_int and the residual moves from the last
  // Trial's configuration to it (a restored state already has it there).
  void RestartSecondGradient(bool move_forces);
  // `force` (N/m, one per forced platen) on the platens' master dofs: f_ext.
  Eigen::VectorXd PlatenLoads(std::span<const double> force) const;
  std::vector<PlatenState> PlatenStates(const Evaluation& ev) const;
  // D for K_t by the chosen operator.
  bool Tangents(const Evaluation& ev, int iteration, std::vector<Tangent>& d, Failure& failure);
  double ForceError(const Evaluation& ev, const Eigen::VectorXd& reduced_residual) const;
  std::map<std::string, SetForces> NodeSetForces(const Evaluation& ev) const;

  Mesh mesh_;
  Boundary boundary_;
  SolverOptions options_;
  GaussPointMaterial* material_;
  DofMap dofs_;
  std::vector<PointGeometry> reference_;  // the Gauss points on the committed configuration
  Eigen::VectorXd displacement_;
  // The last converged Trial on the committed configuration (before the
  // first step: the Trial at ΔF = I): where every step starts.
  Evaluation committed_;
  std::vector<Tangent> initial_tangents_;  // kInitialElastic's
  Eigen::VectorXd last_rate_;              // SolverState::last_rate
  std::optional<SecondGradient> second_gradient_;
  SecondGradientState sg_committed_;
  // diag(T, I): the displacements' elimination with the second gradient's
  // unknowns (all free) after them; empty without a second gradient.
  Eigen::SparseMatrix<double> expand_full_;
  std::map<std::string, SetForces> forces_;  // at the last commit
  std::vector<PlatenState> platens_;         // at the last commit
  int steps_ = 0;
  int trials_ = 0;  // in the current step
};

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_STATIC_SOLVER_H_
