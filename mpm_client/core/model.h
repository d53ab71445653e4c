// Plain data describing a 2-D MPM problem (plane strain, y up, SI units):
// the background grid, solver settings, material regions, walls, rigid
// bodies and surface tractions. The case parser fills it, the solver and the
// simulation driver read it. Stresses: Cauchy, tension positive (as on the
// wire); the case format states pressures as compression positive and the
// parser converts.
#ifndef RVEHUB_MPM_CLIENT_CORE_MODEL_H_
#define RVEHUB_MPM_CLIENT_CORE_MODEL_H_

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "client_case/spec/check_spec.h"
#include "client_case/spec/rve_spec.h"

namespace rvehub::mpm {

// The RVE templates and controls, as every continuum client's case holds them.
using client_case::RveSpec;
using client_case::TemplateSpec;

inline constexpr double kNever = std::numeric_limits<double>::infinity();

enum class ShapeKind {
  kLinear,  // bilinear hat functions, support one cell each side
  kGimp,    // uniform GIMP (particle half-size lp), support h + lp each side
};

// What happens when a material point's centre or loaded surface leaves the
// grid (a point thrown out of a shear band or a heave).
enum class LostPointPolicy {
  kStop,  // the step fails: OutOfRange, naming the point
  kDrop,  // the point is parked where it left: off the grid it takes and
          // gives nothing (no mass, force or load on nodes, ΔF = I), keeps
          // its mass and RVE, and is left out of the timeseries' averages
          // and extents; dry cases only
};

// Which volume change a material point's RVE gets each step.
enum class FBar {
  kNone,   // its own: det ΔF_p from the grid velocities at the point
  kNodal,  // F-bar: det ΔF averaged over the nodes around it (each node the
           // volume-weighted mean of the points it supports, interpolated
           // back), the deviatoric part its own, and the mean stress in the
           // internal forces averaged alike. A point's volume cannot then
           // change alone while its neighbours' do otherwise: the volumetric
           // checkerboard of one point per cell, or one row of a cell dilated
           // open beside another carrying its share (the forces see only the
           // sum of σyy over a cell's rows). In a saturated case it acts on
           // the effective stress
};

struct GridSpec {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // m, lower-left corner
  double cell_size = 0.1;                            // h, m (square cells)
  int nx = 1;                                        // cells along x
  int ny = 1;                                        // cells along y
};

// A sinusoidal shake at time t (s): velocity amplitude·sin(2π f t) (m/s,
// amplitude in m/s, frequency f in Hz), and the displacement since t = 0,
// its integral amplitude·(1 − cos 2π f t)/(2π f) (m). Zero when f is 0.
inline Eigen::Vector2d ShakingVelocity(const Eigen::Vector2d& amplitude, double frequency,
                                       double t) {
  if (!(frequency > 0.0)) return Eigen::Vector2d::Zero();
  return amplitude * std::sin(2.0 * std::numbers::pi * frequency * t);
}
inline Eigen::Vector2d ShakingDisplacement(const Eigen::Vector2d& amplitude, double frequency,
                                           double t) {
  if (!(frequency > 0.0)) return Eigen::Vector2d::Zero();
  const double omega = 2.0 * std::numbers::pi * frequency;  // rad/s
  return amplitude * ((1.0 - std::cos(omega * t)) / omega);
}

struct SolverSpec {
  ShapeKind shape = ShapeKind::kLinear;
  double pic_fraction = 0.1;  // α_PIC in v = α v_PIC + (1 − α) v_FLIP, [0, 1]
  Eigen::Vector2d gravity = Eigen::Vector2d::Zero();  // m/s², e.g. (0, −9.81)
  double time_step = 0.0;  // s; 0: from the CFL number and the P-wave speed
  double cfl = 0.5;        // Δt = cfl·h/c, c = sqrt(M/ρ), when time_step is 0
  // P-wave modulus M = K + 4G/3 for the CFL time step, Pa; 0: from the RVEs'
  // contact tangent at the start (the largest TangentWaveModulus over the
  // points).
  double wave_modulus = 0.0;
  // MPM steps between updates of the CFL step; 0: Δt fixed at the start.
  // Every N steps Δt = cfl·h/max_p (c_p + |v_p|), c_p = sqrt(M_p/(s·ρ_p)) from
  // each point's RVE's current contact tangent M_p (its largest normal
  // component) and the point's current density ρ_p = m/V (s: mass_scale),
  // v_p its velocity: the step keeps the CFL number it was asked for while
  // the soil stiffens or densifies under load, and lengthens where it
  // softens. Needs time_step and wave_modulus 0; dry cases only.
  std::int64_t time_step_update_every = 0;
  double end_time = 1.0;   // s, simulated
  double thickness = 1.0;  // out-of-plane thickness of the macro domain, m
  // A shaking table carrying the whole grid with its walls and bodies (a
  // rigid box): the box's velocity is shaking_amplitude·sin(2π·frequency·t)
  // (m/s, Hz; ShakingVelocity). The step runs in the box's frame, where the
  // soil and the water feel the extra body force −m·dv/dt: exact however far
  // the box moves, where a wall shaken on its own grid line (Wall) is right
  // only for displacements well below a cell. Positions and velocities are
  // then relative to the box; monitors report displacements with the box's
  // added (relative to the ground).
  Eigen::Vector2d shaking_amplitude = Eigen::Vector2d::Zero();  // m/s
  double shaking_frequency = 0.0;                               // Hz
  LostPointPolicy lost_points = LostPointPolicy::kStop;
  // Mass scaling for quasi-static dry runs: the grid's inertia is s times the
  // material's (gravity still acts on the real mass), so the CFL step is
  // sqrt(s) times longer. Kinetic energy and outputs keep the real mass. 1:
  // none, [-].
  double mass_scale = 1.0;
  FBar f_bar = FBar::kNone;
  // Nonlocal strain, m: the radius ℓ over which each point's strain
  // increment is averaged (NonlocalMap, a bell weight), with the stresses in
  // the internal forces averaged alike. A softening band is then about ℓ
  // wide whatever the mesh. 0: off (each point its own increment); dry cases
  // only, not with f_bar.
  double nonlocal_radius = 0.0;
  // The share m of the nonlocal average in each point's strain: (1 − m) its
  // own + m averaged (NonlocalMap), [-], in (0, 1]. ½ by default: the full
  // average leaves a strain alternating from point to point almost no
  // stiffness, and biaxial M1 lost a point at 5.5 % with it.
  double nonlocal_fraction = 0.5;
};

// The box's velocity at time t (s), m/s (SolverSpec::shaking_amplitude).
inline Eigen::Vector2d FrameVelocity(const SolverSpec& solver, double t) {
  return ShakingVelocity(solver.shaking_amplitude, solver.shaking_frequency, t);
}
inline Eigen::Vector2d FrameDisplacement(const SolverSpec& solver, double t) {
  return ShakingDisplacement(solver.shaking_amplitude, solver.shaking_frequency, t);
}

// Where the initial stress of a region's RVEs comes from, its stresses taken from each point's
// depth — kTemplate: the template's own state (e.g. isotropic p0); kIsotropic: p = σv at the
// point's depth (+ surcharge); kK0: σyy = σv, σxx = K0·σv.
enum class InitialStressKind { kTemplate, kIsotropic, kK0 };

// A rectangle filled with material points on a regular pattern:
// points_per_cell_side² points per cell, at the cell's Gauss-like sub-centres.
struct MaterialRegion {
  std::string name;
  Eigen::Vector2d lower = Eigen::Vector2d::Zero();  // m, must lie on grid lines
  Eigen::Vector2d upper = Eigen::Vector2d::Zero();  // m
  int points_per_cell_side = 2;
  std::string rve_template;  // name of a TemplateSpec
  // Bulk density of the dry soil, kg/m³; 0: ρ_s/(1 + e) of the template
  // (solid density over one plus the 2-D void ratio).
  double density = 0.0;
  InitialStressKind initial_stress = InitialStressKind::kTemplate;
  double k0 = 0.5;              // σxx/σyy for kK0, [-]
  double surface_y = 0.0;       // m, ground surface for the depth of geostatic starts
  double surcharge = 0.0;       // Pa, compression +, added to σv at every depth
  double minimum_stress = 0.0;  // Pa, compression +: floor on σv (RVEs need p > 0)
};

// Piecewise-linear velocity history: v(t) interpolated between the points,
// held at the last value after it, m/s.
struct VelocityPoint {
  double time = 0.0;  // s
  Eigen::Vector2d velocity = Eigen::Vector2d::Zero();
};

enum class ContactKind {
  kRough,       // no slip: the node moves with the wall/body
  kSmooth,      // normal velocity only; tangential free
  kFrictional,  // Coulomb: tangential velocity reduced by μ·|Δv_n|
};

// A straight boundary on a grid line (x = position or y = position) acting
// on the nodes of that line. Fixed = rough; roller and symmetry = smooth.
// Bilateral by default (the normal velocity is set to the wall's, a
// symmetry plane or a glued base); unilateral walls hold only nodes that
// approach them, so the soil can separate (a base the soil may bounce off).
struct Wall {
  std::string name;
  int axis = 1;           // 0: the line x = position; 1: the line y = position
  double position = 0.0;  // m, on a grid line
  ContactKind contact = ContactKind::kSmooth;
  double friction = 0.0;        // μ for kFrictional, [-]
  double remove_time = kNever;  // s: the wall is gone from then on (a gate)
  bool unilateral = false;
  // A shaken wall (a shaking table, a shaken box): its velocity is
  // amplitude · sin(2π · frequency · t), m/s, held by the nodes of its grid
  // line (the line stays where it is: for displacements well below a cell).
  Eigen::Vector2d shaking_amplitude = Eigen::Vector2d::Zero();  // m/s
  double shaking_frequency = 0.0;                               // Hz
};

// The velocity of `wall` at time t (s), m/s: zero unless shaken.
inline Eigen::Vector2d WallVelocity(const Wall& wall, double t) {
  return ShakingVelocity(wall.shaking_amplitude, wall.shaking_frequency, t);
}

// A rigid body with a prescribed velocity history. It meets the soil at the
// soil's surface (mpm_client/core/body_contact.h): the faces of the material
// points near it may not approach it; rough: no slip while pressing;
// smooth: no friction; frictional: Coulomb. The soil can separate from it.
// In a saturated case it is impermeable: the water slides along it but does
// not enter it, and the soil pressed against it is no drained free surface
// (a gap that opens under a body fills with nothing: mixed dry and
// saturated domains are out of scope).
struct RigidBody {
  enum class Shape { kRectangle, kCircle };
  std::string name;
  Shape shape = Shape::kRectangle;
  Eigen::Vector2d center = Eigen::Vector2d::Zero();     // m, at t = 0
  Eigen::Vector2d half_size = Eigen::Vector2d::Zero();  // m (rectangle)
  double radius = 0.0;                                  // m (circle)
  ContactKind contact = ContactKind::kRough;
  double friction = 0.0;                // μ for kFrictional
  std::vector<VelocityPoint> velocity;  // empty: at rest
};

// A point of a load's time history: at `time` the load is `factor` × its
// traction, interpolated linearly between points.
struct LoadFactorPoint {
  double time = 0.0;    // s
  double factor = 0.0;  // [-]
};

// A traction on the free surface of a region, carried by the material points
// within one point spacing of the surface: force = traction × surface length
// per point (current length) × thickness, applied at the point's surface
// position. Traction in Pa, as a vector (tension +: a 100 kPa pressure on a
// surface with outward normal +x is (−1e5, 0)). Ramped linearly from zero
// over ramp_time, or scaled by `history` when that is given (an impulse).
struct SurfaceTraction {
  std::string name;
  std::string region;                                  // a MaterialRegion name
  int normal_axis = 0;                                 // outward normal along x (0) or y (1)
  int normal_sign = 1;                                 // +1 or −1
  Eigen::Vector2d traction = Eigen::Vector2d::Zero();  // Pa
  double ramp_time = 0.0;                              // s
  // Times strictly increasing; the factor is held at the first value before
  // the first time and at the last after the last. Empty: the ramp.
  std::vector<LoadFactorPoint> history;
  // Only points whose coordinate along the surface lies in [from, to], m.
  double from = -std::numeric_limits<double>::infinity();
  double to = std::numeric_limits<double>::infinity();
};

struct OutputSpec {
  std::int64_t frame_every = 100;  // MPM steps between results.h5 frames
  // Frames also at the steps nearest to these times (s, increasing): the
  // published instants of a validation (consolidation isochrones).
  std::vector<double> frame_times;
  std::int64_t timeseries_every = 10;  // MPM steps between timeseries.csv rows
  std::int64_t checkpoint_every = 0;   // MPM steps between checkpoints; 0: none
  std::int64_t progress_every = 100;   // MPM steps between progress lines
  // Standard plot written as plot.png: "stress-strain" (mean σyy vs εyy),
  // "load-settlement" (a body's fy vs its displacement), or "none".
  std::string plot = "stress-strain";
  std::string plot_body;    // body for load-settlement
  double plot_width = 1.0;  // m, footing width B for load normalisation q = fy/(B·t)
  // Headline figures written to summary.json (mpm_client/run/summary.h):
  // "footing", "pipe", "collapse", "biaxial", "shaking", "consolidation",
  // "crs", "wave", "none"; empty: from `plot`
  // (load-settlement: footing; stress-strain: biaxial; none: none).
  std::string summary;
  // φ' of the soil for Prandtl's N_q (footing summary), degrees; 0: not given.
  double phi_deg = 0.0;
  // The skeleton's constrained modulus M for Terzaghi's c_v (consolidation
  // summary), Pa; 0: not given.
  double constrained_modulus = 0.0;
  // The wave summary's two monitors (phases.monitors) on the surface, the
  // wave running from the first to the second, and the time from the start
  // over which their u_y traces are compared, s: it must end before the
  // first reflection from a side reaches them.
  std::string wave_from;
  std::string wave_to;
  double wave_window = 0.0;
  // An `rve_cli element-test` CSV (absolute path; the case file may give it
  // relative to itself) drawn on the stress-strain plot's nominal curve as
  // the DEM element test on the same RVE: syy (Pa) against axial_strain.
  std::string reference_curve;
};

// A drained boundary of a saturated case: the grid nodes of a grid line
// (within [from, to] along it) that carry material hold the pore pressure.
// On a wall's line it is a porous stone: the wall holds the soil, the water
// passes.
struct DrainedBoundary {
  std::string name;
  int axis = 1;           // 0: the line x = position; 1: the line y = position
  double position = 0.0;  // m, on a grid line
  double pressure = 0.0;  // Pa, compression + (0: free drainage)
  double from = -std::numeric_limits<double>::infinity();  // m, along the line
  double to = std::numeric_limits<double>::infinity();
};

// A point of a saturated case whose pore pressure timeseries.csv records
// (the material point nearest to `position` at the start).
struct PressureMonitor {
  std::string name;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // m
};

// Saturated soil, one-point two-phase u–v–p MPM (liang-zhao-wu-soga-2023
// §2.2–3): present when the case has a "phases" section. Grains and fluid
// are incompressible; the fluid drags on the skeleton by Darcy's law with a
// permeability k = c·e³/(1 + e) that follows the void ratio. Every face that
// is not drained is impermeable.
// How the saturated step splits velocity and pore pressure (two_phase_solver.cc).
enum class Projection {
  // The paper's eqs. 6–10: the intermediate velocities carry p^n and the
  // Poisson equation gives p^{n+1} − p^n; the correction has no drag.
  // Accurate for consolidation, shaking and collapse; in a 2-D impulse at
  // k ≤ 1e-4 m/s its spurious pressure modes grow (not stabilised). The
  // same modes make a sharp front ring at small steps: the consolidation
  // column at n = 0.162 is 3.2 % from the exact isochrone at CFL 0.5 but
  // 10.1 % at CFL 0.05 (±5 % from node to node), so keep CFL ≥ 0.2 with it.
  kIncremental,
  // Non-incremental in the excess over the water at rest, the drag implicit
  // in the correction too: stable for dynamic problems at any k, with a
  // first-order splitting error in Δt (larger than the incremental one).
  kStabilised,
};

// What the excess pore pressure of the outputs is counted from (the step
// itself does not use it).
enum class ExcessDatum {
  // The water at rest under the initial water table, ρ_f·g·(y_w − y).
  kWaterTable,
  // The water at rest filling the material to its current top surface
  // (SurfaceProfile over the grid's columns): for a flow, whose surface
  // falls, where the first datum would read the lowered table as suction.
  kSurface,
};

struct PhasesSpec {
  bool saturated = false;
  Projection projection = Projection::kIncremental;
  double fluid_density = 1000.0;  // ρ_f, kg/m³
  double permeability = 1e-3;     // k (hydraulic conductivity) at the initial void ratio, m/s
  // Initial porosity n0, [-]; 0: each point's from its RVE, n0 = e0/(1 + e0).
  double porosity = 0.0;
  // y of the free water surface for a hydrostatic start, p = ρ_f·g·(y_w − y)
  // below it (g = |gravity|), m; absent (+∞): p = 0 at the start.
  double water_table = std::numeric_limits<double>::infinity();
  // The nodes at the material's free surface (less than 0.9 of their
  // volume in soil: ½ on a flat face) hold p = 0 as well: a surface that
  // moves (a collapse).
  bool drained_free_surface = false;
  // With drained_free_surface: a node beside one that has mass but less than
  // 0.4 of its volume in soil (a face that has just moved into a new cell)
  // holds p = 0 too. Fine cells need it (a moving face otherwise grows the
  // pore pressure next to it with alternating sign: two_phase_solver.cc).
  bool free_surface_beside_light_nodes = false;
  ExcessDatum excess_from = ExcessDatum::kWaterTable;
  std::vector<DrainedBoundary> drained;
  std::vector<PressureMonitor> monitors;
};

struct CaseSpec {
  std::string name;
  std::string description;
  double expected_runtime_s = 0.0;  // on a 2-core machine, embedded servers
  GridSpec grid;
  SolverSpec solver;
  std::vector<TemplateSpec> templates;
  std::vector<MaterialRegion> regions;
  std::vector<Wall> walls;
  std::vector<RigidBody> bodies;
  std::vector<SurfaceTraction> tractions;
  RveSpec rve;
  PhasesSpec phases;
  OutputSpec output;
  // Validation checks of the run's summary.json (cases/FORMAT.md); the run
  // does not use them.
  std::vector<client_case::CheckSpec> checks;
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_MODEL_H_
