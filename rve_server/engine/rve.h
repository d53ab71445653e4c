// One representative volume element: a 2-D periodic packing of discs driven
// by its cell (deformation gradient or mixed stress/strain control) and
// homogenised into continuum quantities.
#ifndef RVEHUB_RVE_SERVER_ENGINE_RVE_H_
#define RVEHUB_RVE_SERVER_ENGINE_RVE_H_

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "absl/status/statusor.h"
#include "rve_server/values/increment.h"
#include "rve_server/values/snapshot.h"
#include "rve_server/values/state.h"

namespace rvehub::dem {

// Asked between DEM steps by the engine's long loops (Apply, Relax, Run,
// consolidation, element tests), every kInterruptCheckSteps steps: OK to go
// on; any other status (a passed deadline, a cancelled call, a server
// shutting down) stops the loop, which returns that status. Lets a caller
// bound work it cannot size beforehand; it never touches the arithmetic.
using Interrupt = std::function<absl::Status()>;
inline constexpr std::int64_t kInterruptCheckSteps = 256;

// Mixed control of the cell for element tests and preparation.
enum class ControlMode { kStrainRate, kStress };
struct ComponentControl {
  ControlMode mode = ControlMode::kStrainRate;
  double value =
      0.0;  // kStrainRate: velocity-gradient component, 1/s; kStress: σ target, Pa (tension +)
};
struct CellControl {
  ComponentControl xx, yy;
  ComponentControl xy;              // L(0,1) (x-velocity grows with y) or σxy
  double max_strain_rate = 1.0;     // 1/s, cap on servo-driven components
  double servo_gain = 0.05;         // fraction of the stress gap closed per step, [-]
  double servo_integral_steps = 0;  // integral time of the servo, in steps; 0: none
  // Servo memory (integral term per component xx, yy, xy, 1/s), carried
  // between Run calls so that a held stress has no steady-state error.
  Eigen::Vector3d servo_integral = Eigen::Vector3d::Zero();
};

// One active contact (or bonded pair) of the current configuration.
struct ContactForce {
  std::uint32_t i = 0, j = 0;
  Eigen::Vector2d branch = Eigen::Vector2d::Zero();  // x_j − x_i (nearest image), m
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();  // n = branch/|branch|
  double overlap = 0.0;           // δ = r_i + r_j − |branch|, m (< 0: stretched bond)
  double normal_force = 0.0;      // fn, N, compression +
  double tangential_force = 0.0;  // ft, N, along t = (−n_y, n_x)
  double kn = 0.0, kt = 0.0;      // current stiffnesses, N/m
  bool bonded = false;
  // Force on particle i, N: −fn·n + ft·t (particle j gets the opposite).
  Eigen::Vector2d ForceOnI() const {
    return -normal_force * normal + tangential_force * Eigen::Vector2d(-normal.y(), normal.x());
  }
};

// What one step's force loop measured (synchronous with the positions it used).
struct StepEnergy {
  double kinetic = 0.0;  // J, at the force evaluation time
  double elastic = 0.0;  // J, stored in normal springs (linear model: ½ kn δ²)
};

class Rve {
 public:
  // Checks the packing (ValidatePacking) and builds caches.
  static absl::StatusOr<Rve> Create(RveSnapshot packing);

  // The full state, contact history included (what Create restores exactly).
  RveSnapshot ToSnapshot() const;
  const Material& material() const { return p_.material; }
  const Eigen::Matrix2d& cell() const { return p_.cell; }
  // Deformation gradient since the reference configuration (flip-proof).
  Eigen::Matrix2d DeformationGradient() const { return p_.cell * p_.reference_cell.inverse(); }
  // Makes the current configuration the reference (F = I).
  void ResetReference() { p_.reference_cell = p_.cell; }
  int num_particles() const { return static_cast<int>(p_.radius.size()); }
  // Entries in the neighbour list (contacts and near pairs); for benchmarks.
  std::size_t num_neighbour_pairs() const { return nbr_j_.size(); }
  // Bytes held by this RVE (state and caches, not shared scratch).
  std::size_t MemoryBytes() const;

  // F_new = ΔF·F_old. ΔF is 3×3 plane strain (ΔF_zz = 1, no out-of-plane
  // coupling). Rejects non-finite ΔF, det ≤ 0, or a stretch/rotation beyond
  // the controls' limits with InvalidArgument, leaving the RVE untouched.
  // A ΔF that would make the cell thinner than twice the pair cutoff (the
  // minimum image needs it) first doubles the cell along the thin direction
  // (DoubleCell); FailedPrecondition, with the RVE untouched, only where that
  // would pass kMaxParticles. InvalidArgument too, before anything changes, when
  // the increment would take more than kMaxStepsPerApply DEM steps, would
  // leave e ≤ 0 (the cell's area below the discs' own: no packing), or the
  // options are out of range. `interrupt` (optional) is asked between steps;
  // when it stops the increment, the RVE is restored to its state before
  // the call and that status is returned.
  absl::StatusOr<RveState> Apply(const Eigen::Matrix3d& delta_f, const ApplyOptions& options = {},
                                 const Interrupt& interrupt = {});

  // Runs `steps` DEM steps under mixed control and returns the state
  // afterwards; updates control.servo_integral (the servo's memory).
  RveState Run(CellControl& control, std::int64_t steps);
  // The same, asking `interrupt` between steps; when it stops the run, its
  // status is returned and the RVE is left where the run stopped.
  absl::StatusOr<RveState> Run(CellControl& control, std::int64_t steps,
                               const Interrupt& interrupt);
  // Relaxes at fixed cell until the unbalanced-force ratio < tolerance or the cap.
  RveState Relax(double tolerance, std::int64_t max_steps);
  // The same, asking `interrupt` between steps (see Run).
  absl::StatusOr<RveState> Relax(double tolerance, std::int64_t max_steps,
                                 const Interrupt& interrupt);

  // Homogenised state of the current configuration. Changes no state: after
  // an increment it reads the sums of the increment's last DEM step; else
  // (after a restore, Run or Relax) it makes them by a contact pass that only
  // reads the history and keeps them as a cache. Not safe to call on one Rve
  // from two threads at once (the cache), like every other member.
  RveState Observe(bool want_tangent = false) const;
  // Observe's stress, volume, void ratio, porosity, permeability, Δt and
  // mass scale (and tangent) alone; the rest stays zero (see
  // ApplyOptions::stress_only). Needs only the stress sums.
  RveState ObserveStress(bool want_tangent = false) const;
  // The active contacts of the current configuration, sorted by (i, j).
  std::vector<ContactForce> Contacts() const;
  // p = −tr σ/2 of the Love–Weber stress (Pa, compression +), from the same
  // sums as Observe (no pass over the contacts after an increment).
  double MeanPressure() const;
  // Current position of particle i in the cell (x = h·s, unwrapped), m.
  Eigen::Vector2d Position(int i) const { return p_.cell * Eigen::Vector2d(p_.sx[i], p_.sy[i]); }

  // Time step Δt (s) from the controls, masses and stiffnesses.
  double time_step() const { return dt_; }
  // Strain rate (1/s) keeping the inertial number at I for pressure p (Pa).
  double QuasiStaticStrainRate(double inertial_number, double pressure) const;
  // Energy of the last step; measured only while tracking is on (it costs
  // a few percent of the step).
  void set_track_energy(bool on) { track_energy_ = on; }
  const StepEnergy& last_step_energy() const { return energy_; }

  // Tiles the cell twice along lattice vector `axis` (0: the first column
  // of the cell, 1: the second): the same infinite periodic packing, with
  // each particle, velocity and contact history twice. The homogenised
  // state and F are unchanged (to rounding); the cost per step doubles. A
  // cell squeezed flat (a point under a footing) goes on this way.
  // FailedPrecondition (nothing changed) past kMaxParticles.
  absl::Status DoubleCell(int axis);
  // Particles after Apply(delta_f): num_particles() times 2 per doubling of
  // the cell that ΔF's squeeze would take first (the plan Apply follows), so
  // that a caller can account the memory before the increment.
  std::int64_t ParticlesAfterApply(const Eigen::Matrix3d& delta_f) const;

  // Changes the friction μ of every contact and clamps the stored tangential
  // forces to the new Coulomb limit. InvalidArgument (nothing changed) for
  // μ < 0 or not finite.
  absl::Status SetFriction(double friction);
  // Bonds every pair now in contact (cemented material); does nothing when
  // the material's bond_cohesion is 0.
  void BondContacts();

 private:
  explicit Rve(RveSnapshot packing);
  // Run and Relax; a null interrupt is never asked. `stopped` gets its status.
  RveState RunSteps(CellControl& control, std::int64_t steps, const Interrupt* interrupt,
                    absl::Status& stopped);
  RveState RelaxSteps(double tolerance, std::int64_t max_steps, const Interrupt* interrupt,
                      absl::Status& stopped);
  struct StepResult {
    Eigen::Matrix2d stress = Eigen::Matrix2d::Zero();  // Pa, this step's contact stress
    Eigen::Vector2d stiffness = Eigen::Vector2d::Zero();  // Pa, (1/V)Σ kn d⁴ n_x⁴ … for the servo
  };
  // What a contact pass measures besides the forces: nothing; the stress and
  // servo stiffness of a forces-first step (Run's servo); the
  // homogenisation sums of the configuration (sums_); or their stress alone
  // (sums_.stress; the other sums stay unknown).
  enum class Measure { kNone, kServo, kSums, kStress };
  template <bool kRolling, bool kBonds, bool kHertz, Measure kMeasure, bool kUpdate>
  StepResult ContactLoop(const Eigen::Matrix2d& l);
  // The contact pass into fx_, fy_, tq_ (and sums_ when measuring): `update`
  // advances the contact history with velocity gradient l (1/s), as a DEM
  // step does; without it the history is only read (a pure recomputation of
  // the state's forces, always measured).
  StepResult Forces(const Eigen::Matrix2d& l, Measure measure, bool update);
  // Velocities and positions advance by Δt with the forces fx_, fy_, tq_.
  void Integrate();
  // One DEM step, forces first: the forces of the current positions, the
  // contact history advancing with velocity gradient l (1/s) for the affine
  // relative motion; then velocities, positions and the cell (to next_cell,
  // m) advance by Δt. `measure`: also sum the step's stress and servo
  // stiffness (and energy), at the positions before the step.
  // Run and Relax (element tests, preparation, consolidation) step this way.
  StepResult Step(const Eigen::Matrix2d& l, const Eigen::Matrix2d& next_cell, bool measure);
  // The same step with the contact pass at its end: velocities and positions
  // advance with the forces the previous step left (recomputed if unknown),
  // then the forces of the new positions follow, the history advancing with
  // l. `measure` (kNone, kSums or kStress): what that pass also sums, so
  // Apply's last step homogenises the new configuration at no extra pass.
  // Leapfrog either way; the two differ only in which l advances the history
  // at a position (the step's own or the next one's).
  StepResult StepForcesLast(const Eigen::Matrix2d& l, const Eigen::Matrix2d& next_cell,
                            Measure measure);
  void AdvanceCell(const Eigen::Matrix2d& next_cell);  // cell, step count, flips, neighbours
  // (1/V)·sym Σ f⊗b summed as the definitions read (ForEachContact), Pa:
  // Run seeds its servo with it, as it always has.
  Eigen::Matrix2d DefinitionStress() const;
  // sums_ for the current state (a read-only contact pass if not known).
  void EnsureSums() const;
  // sums_.stress for the current state (EnsureSums if not known).
  void EnsureStress() const;
  // The state's stress, volume, void ratio, porosity, permeability, Δt,
  // mass scale and (want_tangent) tangent, from the known stress sums.
  RveState ObserveCommon(bool want_tangent) const;
  // e of a cell of area A (m²): (A − A_s)/A_s with A_s the discs' own area
  // (overlaps not taken out), so at or below 0 once they exceed the voids.
  double VoidRatioOfArea(double area) const { return (area - solid_area_) / solid_area_; }
  void MaybeRebuild();
  void Rebuild(const std::vector<ContactHistory>& history);
  void MaybeFlip();
  // The cell doublings Apply makes before ΔF = f (the axis of each, −1 for
  // none; at most two: ΔF's stretch is bounded), and the cell f·h they lead to.
  Eigen::Matrix2d PlanDoublings(const Eigen::Matrix2d& f, int (&axes)[2]) const;
  void ApplyRigidRotation(double angle);
  std::vector<ContactHistory> CollectHistory() const;
  double Cutoff() const;  // m, pair distance beyond which discs are not listed
  // x_j − x_i to the nearest image of j, m (needs a reduced, large-enough cell).
  Eigen::Vector2d Branch(std::uint32_t i, std::uint32_t j) const;
  // Calls f(const ContactForce&), or f(contact, list index k), for every
  // active contact, in (i, j) order.
  template <typename F>
  void ForEachContact(F&& f) const;

  RveSnapshot p_;  // p_.contacts stays empty: the history lives in the list
  // Caches of the current configuration, never part of the state: each DEM
  // step ends with the contact pass of its new positions, which the next step
  // integrates with and, when measured, which Observe reads, so homogenising
  // an increment costs no pass of its own. A restored RVE recomputes them
  // from the state by a pass that only reads the contact history, with the
  // same operations in the same order: the same bits, so a resumed run stays
  // bit-identical.
  struct Sums {
    Eigen::Matrix2d stress = Eigen::Matrix2d::Zero();  // sym Σ f⊗b (force on i ⊗ branch i→j), N·m
    Eigen::Matrix2d fabric = Eigen::Matrix2d::Zero();  // Σ n⊗n (yy as Nc − xx: |n| = 1), [-]
    double force_sum = 0.0;                            // Σ |f|, N
    std::int64_t num_contacts = 0;
    std::int64_t rattlers0 = 0, rattlers1 = 0;  // particles with 0 and with 1 contact
  };
  std::vector<double> fx_, fy_, tq_;  // contact force (N) and torque (N·m) per particle
  Sums sums_;
  double last_elastic_ = 0.0;  // J, in the normal springs at the last measured pass
  bool forces_valid_ = false;  // fx_, fy_, tq_ belong to the current positions
  bool sums_valid_ = false;    // sums_ too
  bool stress_valid_ = false;  // sums_.stress too (true whenever sums_valid_ is)
  double dt_ = 0.0;
  // Half Verlet list in CSR form, rows i ascending, columns j > i ascending.
  std::vector<std::uint32_t> row_start_;
  std::vector<std::uint32_t> nbr_i_, nbr_j_;  // pair k = (nbr_i_[k], nbr_j_[k]), row-major
  std::vector<double> nbr_kn_;                // N/m, E·r* per pair (linear model)
  std::vector<double> nbr_ft_, nbr_moment_, nbr_bond_;
  // Rebuild trigger: cell at the last rebuild and a bound on the largest
  // fluctuation displacement since.
  Eigen::Matrix2d cell_at_build_ = Eigen::Matrix2d::Identity();
  double displacement_bound_ = 0.0;
  std::vector<double> inv_mass_, inv_inertia_;  // 1/kg, 1/(kg m²), mass-scaled
  StepEnergy energy_;
  bool track_energy_ = false;
  double radius_min_ = 0.0, radius_max_ = 0.0, radius_mean_ = 0.0, solid_area_ = 0.0;
};

// Every check a packing must pass before an RVE is built from it, on every
// path (templates, imports, checkpoints): material and controls, array
// sizes, finiteness, particle count, cell against particle size and the
// neighbour-grid size, contacts. InvalidArgument naming the first problem.
absl::Status ValidatePacking(const RveSnapshot& p);

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_ENGINE_RVE_H_
