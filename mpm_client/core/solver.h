// The MPM solver's shared part: material points on a fixed background grid
// with walls, rigid bodies, gravity and surface tractions, and the state and
// stages the time-stepping schemes share (class Solver; the schemes derive
// from it). It knows nothing of RVEs: stresses come from a StressModel.
// Plane strain, y up, SI units, Cauchy stress with tension positive.
// Single-threaded and deterministic: the same input gives bit-identical
// output.
#ifndef RVEHUB_MPM_CLIENT_CORE_SOLVER_H_
#define RVEHUB_MPM_CLIENT_CORE_SOLVER_H_

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mpm_client/core/body_contact.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/nonlocal.h"
#include "mpm_client/core/shape.h"

namespace rvehub::mpm {

// What the constitutive side returns per point.
struct PointResponse {
  Eigen::Matrix3d stress = Eigen::Matrix3d::Zero();  // Cauchy, Pa, tension +
  double void_ratio = 0.0;                           // [-]
  double fabric_anisotropy = 0.0;                    // [-]
  double mean_rotation = 0.0;                        // rad
  double coordination = 0.0;                         // [-]
  double permeability = 0.0;                         // m/s
};

// The RVEs behind the material points (or a test material).
class StressModel {
 public:
  virtual ~StressModel() = default;
  // Applies each point's incremental deformation gradient ΔF (3×3 plane
  // strain, ΔF_zz = 1) for MPM step `step` (1-based) and fills out[p]
  // (delta_f.size() == out.size() == number of points).
  virtual absl::Status Update(std::int64_t step, std::span<const Eigen::Matrix3d> delta_f,
                              std::span<PointResponse> out) = 0;
  // While set, the caller reads only out[p].stress, void_ratio and
  // permeability of the Updates: a model may measure those alone and leave
  // the other fields undefined (the RVEs then do). Default: ignored.
  virtual void SetStressOnly(bool stress_only) { (void)stress_only; }
};

// A surface traction carried by one material point (see SurfaceTraction).
struct SurfaceLoad {
  std::int32_t point = 0;                              // index into MaterialPoints
  Eigen::Vector2d traction = Eigen::Vector2d::Zero();  // Pa, tension +, after the ramp
  double length0 = 0.0;                                // m, surface length at the start
  int normal_axis = 0;                                 // outward normal along x (0) or y (1)
  int normal_sign = 1;                                 // +1 or −1
  double ramp_time = 0.0;                              // s, linear ramp from zero
  std::int32_t source = -1;  // index into CaseSpec::tractions (its history), −1: none
};

// Material points as structure of arrays (all arrays have size()).
struct MaterialPoints {
  std::vector<Eigen::Vector2d> position;    // m
  std::vector<Eigen::Vector2d> velocity;    // m/s
  std::vector<double> mass;                 // kg (for the domain thickness)
  std::vector<double> volume;               // m³, current (area × thickness)
  std::vector<double> volume0;              // m³, at the start
  std::vector<Eigen::Matrix2d> F;           // total deformation gradient, in-plane
  std::vector<Eigen::Matrix3d> stress;      // Pa, tension +
  std::vector<Eigen::Vector2d> half_size0;  // m, GIMP lp at the start
  std::vector<std::int32_t> region;         // index into CaseSpec::regions
  std::vector<PointResponse> response;      // last response of the model
  std::vector<SurfaceLoad> loads;           // any number per point
  // Saturated cases only (zero in dry ones): `mass` is then the solids'.
  std::vector<Eigen::Vector2d> fluid_velocity;  // m/s
  std::vector<double> pore_pressure;            // p, Pa, compression +
  std::vector<double> porosity0;                // n at the start, [-]
  std::vector<Eigen::Vector2d> position0;       // m, at the start (settlement, monitors)
  std::vector<double> vertical_stress0;         // σ'yy,0 of the excess ratio, Pa, compression +

  std::size_t size() const { return position.size(); }
  // Resizes every per-point array (new points: zero, F = I).
  void Resize(std::size_t n);
};

// Bulk density of a region, kg/m³, for regions whose spec density is 0.
using RegionDensity = std::function<absl::StatusOr<double>(int region)>;

// Fills the case's regions with points_per_cell_side² points per cell at the
// sub-cell centres, region by region, rows from the bottom, left to right:
// volume = (h/ppc)²·thickness, half sizes h/(2 ppc), mass = density·volume,
// F = I, velocity and stress zero (the driver sets the stress from the RVEs).
// Surface tractions go to the outermost layer of points of their region
// (within one point spacing of the surface, inside [from, to]), each carrying
// one point spacing of surface.
absl::StatusOr<MaterialPoints> FillRegions(const CaseSpec& spec, const RegionDensity& density = {});
// The same with one density per region (used where the spec says 0).
absl::StatusOr<MaterialPoints> FillRegions(const CaseSpec& spec,
                                           const std::vector<double>& density);

// c = sqrt(M/ρ), the P-wave speed of a material of P-wave modulus M (Pa) and
// density ρ (kg/m³): m/s.
double WaveSpeed(double wave_modulus, double density);
// The P-wave modulus an RVE's 9×9 contact tangent D[3i+j][3k+l] (Pa) gives
// for the CFL step: its larger in-plane normal component, max(D_xxxx, D_yyyy),
// Pa (an upper bound of the relaxed modulus: the contacts' own stiffness).
double TangentWaveModulus(const Eigen::Matrix<double, 9, 9>& tangent);
// Δt = cfl·h/c with c = WaveSpeed(M, ρ): s.
double CflTimeStep(double cfl, double cell_size, double wave_modulus, double density);

// Piecewise-linear velocity history (held at the first value before the
// first point and at the last after it), m/s, and its integral from 0 to t, m.
Eigen::Vector2d VelocityAt(const std::vector<VelocityPoint>& history, double t);
Eigen::Vector2d DisplacementAt(const std::vector<VelocityPoint>& history, double t);
// A load's factor at time t: its history interpolated (held at the ends), or
// the linear ramp min(1, t/ramp_time) when the history is empty, [-].
double LoadFactorAt(const std::vector<LoadFactorPoint>& history, double ramp_time, double t);

// The in-plane deformation increment a material point's RVE gets: the
// continuum's df, except that a packing that carries no stress at all (its
// last result, `last`) and is at or above max_void_ratio (> 0) is not opened
// further: a dilating df (det > 1) loses its volume change, df/sqrt(det df),
// keeping its shear and rotation. Only a stress-free packing: one that still
// pushed would do work on the continuum as it opens without unloading. [-]
Eigen::Matrix2d RveIncrement(const Eigen::Matrix2d& df, const PointResponse& last,
                             double max_void_ratio);

// The nodal average of a per-point quantity a: at each node the weighted mean
// a_I = Σ_q S_Iq w_q a_q / Σ_q S_Iq w_q of the points it supports, and back
// at each point ā_p = Σ_I S_Ip a_I / Σ_I S_Ip over its nodes that some point
// of weight > 0 reaches. Points without nodes (parked off the grid) and
// points of weight 0 keep their own value; the latter add nothing to the
// nodes. shapes, weight and value have one entry per point; node_count is
// the grid's.
std::vector<double> NodalAverage(std::span<const ShapeValues> shapes,
                                 std::span<const double> weight, std::span<const double> value,
                                 int node_count);

// Void ratio from which a packing without any stress has come apart from
// the soil around it (F-bar leaves it out, HasComeApart), [-]: n = 0.5, far
// looser than any disc packing that still holds contacts (the sets here
// lose their last ones near e 0.3), so only points thrown clear or swollen
// away from the soil are concerned, never a packing opened inside a cell.
inline constexpr double kApartVoidRatio = 1.0;

// Whether F-bar leaves a point out, from its last result: its packing
// carries no stress at all and its void ratio is at least kApartVoidRatio.
// Such a point takes its own volume change and stress and adds nothing to
// the averages. Kept in, its share of its neighbours' mean stress pushes
// its nodes apart with a force in proportion to its own volume, which it
// then gains: a saturated scatter point in collapse-saturated-medium swelled
// so to e = 115 and blew up at 3.62 s (docs/f-bar-and-nonlocal-strain.md).
bool HasComeApart(const PointResponse& last);

// F-bar with a nodal average (SolverSpec::f_bar kNodal): each point's
// in-plane increment df_p scaled to the determinant J̄_p, the NodalAverage of
// J = det df weighted by the volumes V_p (m³; 0 for a point left out, which
// keeps its df): df_p ← (J̄_p/J_p)^{1/2} df_p,
// its shear and rotation kept. A homogeneous increment is unchanged (to
// rounding) and Σ V_p J_p is kept. The solver's internal forces then use the
// in-plane mean stress averaged by the same map (its adjoint), so that the
// forces do the work the RVEs take.
void AverageVolumeChange(std::span<const ShapeValues> shapes, std::span<const double> volume,
                         int node_count, std::span<Eigen::Matrix2d> df);

// The shared part of the MPM time-stepping schemes: the case (grid, walls,
// bodies, tractions), the material points, time, Δt and step count, the
// reactions, and the stages both schemes use — shape functions, the walls'
// and bodies' constraints, the stress update through the StressModel (with
// F-bar and the nonlocal strain), the internal forces' stresses, surface
// loads, the points' move off walls. One class per scheme derives from it,
// in the manner of cb-geo mpm's mpm_explicit / mpm_semi_implicit_twophase:
// ExplicitSolver (explicit_solver.h), the dry USF step of Liang & Zhao
// §2.3, and TwoPhaseSolver (two_phase_solver.h), the semi-implicit u–v–p
// step of liang-zhao-wu-soga-2023. ForCase (and so Create) picks one from
// the case. The checkpoint's flat arrays live in solver_checkpoint.h.
class Solver {
 public:
  virtual ~Solver() = default;
  Solver(const Solver&) = delete;
  Solver& operator=(const Solver&) = delete;

  // The scheme for the case, its spec validated (grid, walls on grid lines,
  // bodies, PIC fraction; a saturated case's phases), without points yet:
  // TwoPhaseSolver where spec.phases.saturated, else ExplicitSolver. Create
  // and a checkpoint (SolverFromState) give it its points. `model` must
  // outlive the solver.
  static absl::StatusOr<std::unique_ptr<Solver>> ForCase(const CaseSpec& spec, StressModel* model);
  // ForCase with the points validated. The time step is dt when positive,
  // else spec.solver.time_step when positive, else the CFL step from
  // spec.solver.wave_modulus when that is positive (with the densest
  // point), else 0 and the caller must set_dt before Step.
  static absl::StatusOr<std::unique_ptr<Solver>> Create(const CaseSpec& spec,
                                                        MaterialPoints initial, StressModel* model,
                                                        double dt = 0.0);

  // One step of size dt of the case's scheme. On an error up to the stress
  // update (a point outside the grid, an inverted point, the model's error
  // or a non-finite response from it) the points are unchanged, but the
  // model may have advanced; on a later one (a load without nodes, a
  // pressure solve that fails, a step that leaves a point's state not
  // finite) they are not, and the run cannot go on from them. Time and step
  // count advance only with a step that succeeds.
  virtual absl::Status Step() = 0;

  // Saturated cases: each point's porosity n = 1 − (1 − n0)/J (grains
  // incompressible), [-], and permeability k = c·e³/(1 + e), m/s.
  double Porosity(std::size_t p) const;
  double Permeability(std::size_t p) const;
  // The mass the step moves, kg: the solids' (the two-phase scheme adds the
  // water's).
  virtual double MixtureMass() const;

  double time() const { return time_; }        // s
  std::int64_t step() const { return step_; }  // steps done
  double dt() const { return dt_; }            // s
  // The next Steps need of the points' responses only the stress, void ratio
  // and permeability (no output reads the rest): the model may measure
  // those alone, and the points keep their other fields as they were.
  void set_stress_only(bool stress_only) { stress_only_ = stress_only; }
  void set_dt(double dt) { dt_ = dt; }
  // Per point, the in-plane stress (Pa, tension +; a saturated case's
  // effective stress) its internal forces use: its own, averaged by the
  // nonlocal map where the case has one, and with F-bar (kNodal) its mean
  // stress replaced by the nodal average, the adjoint of the volume-change
  // map (points left out of F-bar, HasComeApart, keep their own). Either way
  // the forces do the work the RVEs take (one formula for the dry and the
  // saturated steps). Public for tests and diagnostics.
  std::vector<Eigen::Matrix2d> ForceStresses() const;
  // F-bar's averaging weights: each point's current volume (m³), 0 for the
  // points left out this step (f_bar_apart_).
  std::vector<double> FBarWeights() const;
  const MaterialPoints& points() const { return points_; }
  // Per point, 1 where it is off the grid and parked (SolverSpec::lost_points
  // kDrop), as of the last step; derived from the positions, so not state.
  const std::vector<std::uint8_t>& lost() const { return lost_; }
  // For the driver to set the initial stresses, responses or velocities;
  // the number of points and loads must stay (Step refuses otherwise).
  MaterialPoints& mutable_points() { return points_; }
  const GridSpec& grid() const { return grid_; }
  // The case's tractions, whose histories a load's source indexes.
  std::size_t traction_count() const { return load_histories_.size(); }

  // The force each wall, then each rigid body (in CaseSpec order) received
  // from the soil in the last step, N (total for the domain thickness):
  // −Σ m_I Δv_I/Δt over its nodes, Δv_I the constraint's change of the nodal
  // velocity after the forces, plus α_PIC times its change of the mapped
  // velocities at the step's start (the part the points keep). Then
  // Δ(Σ m_p v_p) = (gravity + tractions − Σ reactions)·Δt exactly. In a
  // saturated case the water's changes count too: the reaction is the
  // mixture's total force, pore pressure included.
  const std::vector<Eigen::Vector2d>& Reactions() const { return reactions_; }
  Eigen::Vector2d BodyDisplacement(int body) const;  // m, centre now − centre at t = 0
  double KineticEnergy() const;                      // J, Σ ½ m v² on the grid
  // J, −Σ m g·x over the points on the grid (zero at the grid's origin and
  // without gravity): with the kinetic energy, the energy budget of a flow.
  double PotentialEnergy() const;

  // Replaces the state with another of the same case (a checkpoint's): the
  // points, time (s), Δt (s), steps done and the last step's reactions (N,
  // one per wall and body). InvalidArgument for points Create would refuse,
  // and then nothing changes.
  absl::Status Restore(MaterialPoints points, double time, double dt, std::int64_t step,
                       std::vector<Eigen::Vector2d> reactions);

 protected:
  // inactive_mass_fraction: nodes lighter than this fraction of the lightest
  // point's inertia are inactive (the scheme's choice), [-].
  explicit Solver(double inactive_mass_fraction)
      : inactive_mass_fraction_(inactive_mass_fraction) {}

  // Validates the spec's shared part and takes it over, then SetUpScheme.
  absl::Status SetUp(const CaseSpec& spec, StressModel* model);
  // The scheme's own part of the spec (called last by SetUp).
  virtual absl::Status SetUpScheme(const CaseSpec& /*spec*/) { return absl::OkStatus(); }
  // What the scheme asks of the initial points beyond the shared checks
  // (Create's).
  virtual absl::Status ValidateInitialPoints(const MaterialPoints& /*points*/) const {
    return absl::OkStatus();
  }
  // Sizes the scratch arrays for the points and finds the inactive-node mass
  // (a scheme sizes its own after calling this).
  virtual void Prepare();

  // The grid line index of `position` (m) along `axis`, or −1 off the lines.
  int GridLine(int axis, double position) const;
  // The nodes on grid line `line` of `axis` (x = const for 0) whose
  // coordinate along the line lies in [from, to] (m, to rounding), in order.
  std::vector<std::int32_t> NodesOnLine(int axis, int line,
                                        double from = -std::numeric_limits<double>::infinity(),
                                        double to = std::numeric_limits<double>::infinity()) const;
  // FailedPrecondition unless Δt > 0 and the points and loads are those the
  // scratch arrays were sized for (every Step's first check).
  absl::Status CheckReady() const;
  // Gravity less the box's acceleration over this step (a shaken box's frame,
  // SolverSpec::shaking_amplitude): (v_box(t + Δt) − v_box(t))/Δt, so that
  // the frame's velocity change is exact, m/s². Per unit of the grid's
  // inertia: under mass scaling gravity acts on the real mass (g/s), the
  // frame's force is inertia and scales with it.
  Eigen::Vector2d BodyAcceleration() const;
  // Shape values of every point and load (at the step's start), and the
  // loads' forces; OutOfRange for a point off the grid. Then the points'
  // faces near each body (contacts_).
  absl::Status EvaluateShapes();
  // Whether a node carries enough mass to take part in the step.
  bool Active(int node) const { return node_mass_[node] > min_node_mass_; }
  // Clears the walls' and bodies' impulses and constrains the nodal
  // velocities mapped at the step's start, node_velocity_. The G2P passes a
  // fraction α (the PIC fraction) of this first correction on to the points
  // (PIC keeps it, FLIP adds only increments), so that fraction belongs to
  // the reactions: then Δ(Σ m v) = (external − Σ reactions)·Δt.
  void ConstrainStart();
  // Applies the walls' and bodies' constraints at time t to the nodal
  // velocities, with the bodies and shaken walls moving at their velocity
  // at body_time;
  // adds weight × (momentum change) of each to impulse_.
  void Constrain(std::vector<Eigen::Vector2d>& velocity, double body_time, double weight);
  // The contacts' constraints on `grid` (the solids' or the water's), the
  // bodies moving at their velocity at body_time; adds weight × the
  // momentum each body gave to impulse_.
  void ResolveBodies(std::span<const SurfaceContact> contacts, std::span<const RigidBody> bodies,
                     ContactGrid grid, double body_time, double weight);
  // A point's new position `to` (m), moved from `from`, held on the line of
  // any wall it would cross or, at the grid's edge, leave the grid through.
  // A GIMP point moves with its domain's mean velocity, which does not
  // vanish at a wall line its domain reaches past: without this its centre
  // creeps through the wall (and, at the grid's edge, off the grid).
  Eigen::Vector2d KeepOffWalls(const Eigen::Vector2d& from, Eigen::Vector2d to) const;
  // ΔF = I + Δt·L with L = Σ_I v_I ⊗ ∇S_Ip from node_velocity_ (the
  // solid's), its volume change averaged over the nodes where the case asks
  // for F-bar, one batched model update, then F, volumes, responses and
  // stresses; FailedPrecondition for a point that would invert.
  absl::Status UpdateStress();
  // Adds each surface load's force (load_force_) to node_force_, spread
  // over the nodes around its surface position that carry mass;
  // FailedPrecondition where none does.
  absl::Status AddLoadForces();
  // The end of every step: FailedPrecondition naming the first point the
  // step has left with a field that is not finite (the step was unstable);
  // else the reactions from the impulses, and time and step count advance.
  absl::Status FinishStep();

  GridSpec grid_;
  SolverSpec solver_;
  PhasesSpec phases_;  // the case's water (porosity and permeability of the points)
  std::vector<Wall> walls_;
  std::vector<RigidBody> bodies_;
  std::vector<std::vector<LoadFactorPoint>> load_histories_;  // per CaseSpec traction
  std::vector<std::vector<std::int32_t>> wall_nodes_;         // nodes on each wall's line
  std::vector<int> wall_lines_;                               // grid line index of each wall
  StressModel* model_ = nullptr;

  MaterialPoints points_;
  double time_ = 0.0;
  double dt_ = 0.0;
  std::int64_t step_ = 0;
  std::vector<Eigen::Vector2d> reactions_;  // N, last step
  const double inactive_mass_fraction_;     // see the constructor
  double min_node_mass_ = 0.0;              // kg: lighter nodes are inactive

  // Scratch reused by every step (no allocation in the step loop).
  std::vector<ShapeValues> shape_;           // per point (none while lost)
  std::vector<std::uint8_t> lost_;           // per point, see lost()
  std::vector<ShapeValues> load_shape_;      // per load, at its surface position
  std::vector<Eigen::Vector2d> load_force_;  // per load, N
  std::vector<double> node_mass_;
  std::vector<Eigen::Vector2d> node_velocity_;  // v^n (after constraints)
  std::vector<Eigen::Vector2d> node_force_;
  std::vector<Eigen::Vector2d> node_velocity_new_;  // v^{n+1}
  std::vector<Eigen::Vector2d> impulse_;            // per wall/body, N·s
  std::vector<std::uint8_t> node_fixed_;            // per node: components a wall holds
  std::vector<SurfaceContact> contacts_;            // faces near bodies, this step
  std::vector<Eigen::Vector2d> body_velocity_;      // per body, m/s

 private:
  // The points' faces near each body at the step's start (contacts_).
  void FindContacts();
  // FailedPrecondition naming the first point the step has left with a
  // field that is not finite.
  absl::Status CheckPointsFinite() const;

  std::vector<Eigen::Matrix2d> in_plane_df_;  // per point, ΔF in-plane (F-bar applied)
  std::vector<std::uint8_t> f_bar_apart_;     // per point, 1: left out of F-bar (HasComeApart)
  NonlocalMap nonlocal_;                      // this step's (solver.nonlocal_radius)
  std::vector<Eigen::Matrix3d> delta_f_;      // per point, the continuum's ΔF
  std::vector<Eigen::Matrix3d> rve_delta_f_;  // per point, what its RVE gets (RveIncrement)
  std::vector<PointResponse> response_;
  bool stress_only_ = false;     // set_stress_only
  double max_void_ratio_ = 0.0;  // RveSpec::max_void_ratio
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_SOLVER_H_
