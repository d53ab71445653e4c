// The explicit MPM solver: material points on a fixed background grid,
// update-stress-first (USF) steps as in Liang & Zhao §2.3, with walls, rigid
// bodies, gravity and surface tractions. It knows nothing of RVEs: stresses
// come from a StressModel. Plane strain, y up, SI units, Cauchy stress with
// tension positive. Single-threaded and deterministic: the same input gives
// bit-identical output.
#ifndef RVEHUB_MPM_CLIENT_SOLVER_H_
#define RVEHUB_MPM_CLIENT_SOLVER_H_

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mpm_client/body_contact.h"
#include "mpm_client/model.h"
#include "mpm_client/nonlocal.h"
#include "mpm_client/shape.h"

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
  std::vector<double> vertical_stress0;         // −σ'yy at the start, Pa, compression +

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
// so to e = 115 and blew up at 3.62 s (cases/README.md).
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

class Solver {
 public:
  // Validates the spec (grid, walls on grid lines, bodies, PIC fraction) and
  // the points. The time step is dt when positive, else spec.solver.time_step
  // when positive, else the CFL step from spec.solver.wave_modulus when that
  // is positive (with the densest point), else 0 and the caller must set_dt
  // before Step. `model` must outlive the solver.
  static absl::StatusOr<std::unique_ptr<Solver>> Create(const CaseSpec& spec,
                                                        MaterialPoints initial, StressModel* model,
                                                        double dt = 0.0);
  // A solver for `spec` with the state of ExportState (a checkpoint).
  static absl::StatusOr<std::unique_ptr<Solver>> FromState(
      const CaseSpec& spec, const std::map<std::string, std::vector<double>>& doubles,
      const std::map<std::string, std::vector<std::int64_t>>& ints, StressModel* model);

  // One explicit USF step of size dt (a saturated case: the semi-implicit
  // two-phase step, StepSaturated). On an error up to the stress update (a
  // point outside the grid, an inverted point, the model's error or a
  // non-finite response from it) the points are unchanged, but the model may
  // have advanced; on a later one (a load without nodes, a pressure solve
  // that fails, a step that leaves a point's state not finite) they are not,
  // and the run cannot go on from them. Time and step count advance only
  // with a step that succeeds.
  absl::Status Step();

  // Saturated cases: each point's porosity n = 1 − (1 − n0)/J (grains
  // incompressible), [-], and permeability k = c·e³/(1 + e), m/s.
  double Porosity(std::size_t p) const;
  double Permeability(std::size_t p) const;
  // Solids' plus fluid's mass, kg.
  double MixtureMass() const;
  // CG iterations of the last pressure solve (saturated), for diagnostics.
  int pressure_iterations() const { return pressure_iterations_; }

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

  // The whole state as named flat arrays (bit-exact), and back into a solver
  // created from the same spec. Keys: see solver.cc.
  void ExportState(std::map<std::string, std::vector<double>>& doubles,
                   std::map<std::string, std::vector<std::int64_t>>& ints) const;
  absl::Status ImportState(const std::map<std::string, std::vector<double>>& doubles,
                           const std::map<std::string, std::vector<std::int64_t>>& ints);

 private:
  Solver() = default;
  // A solver for the spec without points (validates the spec).
  static absl::StatusOr<std::unique_ptr<Solver>> Init(const CaseSpec& spec, StressModel* model);
  // Gravity less the box's acceleration over this step (a shaken box's frame,
  // SolverSpec::shaking_amplitude): (v_box(t + Δt) − v_box(t))/Δt, so that
  // the frame's velocity change is exact, m/s². Per unit of the grid's
  // inertia: under mass scaling gravity acts on the real mass (g/s), the
  // frame's force is inertia and scales with it.
  Eigen::Vector2d BodyAcceleration() const;
  // Sizes the scratch arrays for the points and finds the inactive-node mass.
  void Prepare();
  // Shape values of every point and load (at the step's start), and the
  // loads' forces; OutOfRange for a point off the grid.
  absl::Status EvaluateShapes();
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
  // The points' faces near each body at the step's start (contacts_).
  void FindContacts();
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
  // The two-phase step (saturated.cc).
  absl::Status StepSaturated();
  // FailedPrecondition naming the first point the step has left with a
  // field that is not finite (the step was unstable); each step checks this
  // before it advances the time.
  absl::Status CheckPointsFinite() const;
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

  GridSpec grid_;
  SolverSpec solver_;
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
  std::vector<Eigen::Matrix2d> in_plane_df_;        // per point, ΔF in-plane (F-bar applied)
  std::vector<std::uint8_t> f_bar_apart_;     // per point, 1: left out of F-bar (HasComeApart)
  NonlocalMap nonlocal_;                      // this step's (solver.nonlocal_radius)
  std::vector<Eigen::Matrix3d> delta_f_;      // per point, the continuum's ΔF
  std::vector<Eigen::Matrix3d> rve_delta_f_;  // per point, what its RVE gets (RveIncrement)
  std::vector<PointResponse> response_;
  bool stress_only_ = false;     // set_stress_only
  double max_void_ratio_ = 0.0;  // RveSpec::max_void_ratio

  // Saturated cases (saturated.cc).
  PhasesSpec phases_;
  std::vector<std::vector<std::int32_t>> drained_nodes_;   // per drained boundary
  std::vector<double> node_fluid_mass_;                    // kg
  std::vector<Eigen::Vector2d> node_fluid_velocity_;       // v_f^n, then v_f*, m/s
  std::vector<Eigen::Vector2d> node_fluid_force_;          // N
  std::vector<Eigen::Vector2d> node_fluid_velocity_new_;   // v_f^{n+1}
  std::vector<Eigen::Vector2d> node_fluid_velocity_star_;  // v_f* before the correction
  std::vector<double> node_drag_;                          // Δt·Σ S·drag·V, kg
  std::vector<double> node_pressure_;                      // p^n, Pa
  // p^{n+1} of the last step per node, Pa; NaN where the node was inactive.
  // Part of the state: the next step's p^n where the node is still active.
  std::vector<double> node_pressure_last_;
  std::vector<double> pressure_fixed_;     // prescribed p, Pa, or NaN
  std::vector<double> node_base_;          // b: p^n or p_r (saturated.cc), Pa
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

#endif  // RVEHUB_MPM_CLIENT_SOLVER_H_
