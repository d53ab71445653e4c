// TwoPhaseSolver, the saturated step: one-point two-phase MPM with the semi-implicit
// fractional-step scheme of liang-zhao-wu-soga-2023 §2.2–3 (u–v–p form).
// The effective stress is explicit (from the model, as in the dry step);
// the Darcy drag and the pore pressure are implicit, so the time step does
// not depend on the permeability or on the fluid's incompressibility.
//
// Two projections (PhasesSpec::projection). kIncremental is the paper's
// eqs. 6–10. kStabilised departs from them twice, both needed for a stable
// step at small k in two dimensions (a surface impulse on a half-space,
// 0.25–0.5 m cells, k ≤ 1e-4 m/s: with kIncremental the kinetic energy grew
// to 1550–2600 times its pulse peak by 0.6 s on 0.5 m cells, faster on
// finer grids and with larger steps; stable at 1e-2 and 1e-3):
// - the projection is non-incremental in the excess pore pressure: the
//   intermediate velocities carry only the water at rest's pressure p_r
//   (hydrostatic below the water table, known in closed form) and the
//   Poisson equation gives p^{n+1} − p_r itself. Solving for p^{n+1} − p^n
//   leaves the pressure of equal-order interpolation without the
//   stabilising Δt-Laplacian, and its spurious modes grew there; solving for
//   the whole p^{n+1} would impose ∂p/∂n = 0 at impermeable walls, 23 % off
//   a hydrostatic base pressure;
// - the correction keeps the drag implicit (the same 2×2 system per node as
//   the intermediate velocities), and the Poisson mobility follows
//   (PressureMobility). Without drag, and without p^n in the intermediate
//   step, the correction would move the water through the skeleton at a
//   rate set by Δt, not k: a seepage error of Δt·n·g, 30 % of k = 1e-3 m/s
//   in the consolidation test. With it a steady seepage obeys Darcy's law
//   exactly, and at k → 0 the phases move together.
// kStabilised's price is its Δt-Laplacian on the whole excess pressure: an
// artificial drainage of order Δt. Measured on collapse-saturated-ci at the
// paper's Δt = 2e-4 s: front at 0.6 s 1.301 m against 1.143 m incremental
// (1.227 and 1.132 m at Δt = 5e-5 s), the dilatant suction relieved sooner.
// So kIncremental stays the default and kStabilised is for dynamic cases
// at small k (the wave propagation).
#include "mpm_client/core/two_phase_solver.h"

#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "mpm_client/core/spd_solve.h"
#include "mpm_client/core/two_phase.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::mpm {
namespace {

using Eigen::Matrix2d;
using Eigen::Vector2d;

// Nodes lighter than this fraction of the lightest point are inactive,
// larger than the dry step's: a node that the edge of a GIMP point's
// domain just reaches has a mass ~ε² and a velocity v* ~ 1/ε (force over
// mass), so its term in the point's ∇·v*, ~ε·(1/ε), stays finite as ε → 0
// and enters the pressure solve at full size. The soil's surface moving by
// micrometres switched such nodes on and off: pressure kicks of 0.1–1 kPa
// at the centre of the cyclic box (elastic skeleton, 0.25 m cells), ringing
// at period 2 for a few steps; none from 1e-6 (0.25 m cells) and 1e-5
// (0.05 m cells) on. The dry step takes its strain from the mapped
// velocities, which are averages of the points', and is not affected.
constexpr double kInactiveMassFraction = 1e-5;
// pressure_fixed_ of a node whose pore pressure is solved for.
constexpr double kFree = std::numeric_limits<double>::quiet_NaN();
// Free surface: nodes with less than this share of soil around them (a flat
// face has ½, a corner ¼, a node just reached by a moving face ~0). A node
// carries an unknown pressure only when nearly full: partly filled nodes
// (shares of 0.55–0.7) made the pressure projection unstable once a face
// moved through a cell — a period-2 growth of the pore pressure at the front
// (×1.77 per step) that ended a soft elastic column at step 450 and the
// RVE-backed collapse at 0.094 s. From 0.7 on both run stable; 0.8 and 0.9
// give the same collapse (kinetic energy within 1.5 %).
constexpr double kSurfaceFraction = 0.9;
// PhasesSpec::free_surface_beside_light_nodes: a node beside one with mass
// but less than this share (a face that has moved less than about 0.9 of a
// cell past the node) is free surface too. Without it, on 0.025–0.05 m cells
// a node of share 0.92 beside a drained one of 0.18 (the face 0.6 h past it)
// grew its pressure ×(−1.2) per step: the §4.3 column with a Mohr–Coulomb
// skeleton ended at 0.09 s on 0.025 m cells (either projection, Δt 2e-4 or
// 1e-4 s), at 0.78 s on 0.04 m and at 1.26 s on 0.05 m, and with RVEs at
// 0.15 s on 0.05 m. The likely cause: the weak form's pressure force pushes
// the face out by the pressure interpolated there (0.4 of the node's), where
// the water's is zero; a strong-form pressure force held the face too, but
// lost the pore pressure's push on walls and platens. Off by default: on
// coarse cells it drains a strip up to two cells wide (collapse-saturated-ci
// on 0.25 m cells: kinetic-energy peak 959 J against 785 J, front at 0.6 s
// 1.388 m against 1.205 m).
constexpr double kLightNeighbourFraction = 0.4;
// Nodes with less than this share hold their pressure (FindDrainedNodes).
constexpr double kEmptyFraction = 1e-3;
// Tikhonov weight of the nodal pressure fit, relative to the lumped diagonal.
constexpr double kFitRegularisation = 1e-9;

absl::Status Invalid(absl::string_view what, absl::string_view why) {
  return absl::InvalidArgumentError(absl::StrCat(what, ": ", why));
}

}  // namespace

TwoPhaseSolver::TwoPhaseSolver() : Solver(kInactiveMassFraction) {}

absl::Status TwoPhaseSolver::SetUpScheme(const CaseSpec& spec) {
  if (solver_.nonlocal_radius > 0.0) {
    return Invalid("solver", "a nonlocal strain is for dry cases only");
  }
  const PhasesSpec& ph = spec.phases;
  if (!(ph.fluid_density > 0.0) || !(ph.permeability > 0.0) ||
      !(ph.porosity >= 0.0 && ph.porosity < 1.0)) {
    return Invalid("phases", "fluid_density and permeability must be > 0, porosity in [0, 1)");
  }
  for (const DrainedBoundary& d : ph.drained) {
    const std::string what = absl::StrCat("drained boundary ", d.name);
    const int line = d.axis == 0 || d.axis == 1 ? GridLine(d.axis, d.position) : -1;
    if (line < 0 || !std::isfinite(d.pressure)) {
      return Invalid(what, "must lie on a grid line with a finite pressure");
    }
    drained_nodes_.push_back(NodesOnLine(d.axis, line, d.from, d.to));
  }
  // Bodies are impermeable and the water slides along them freely.
  fluid_bodies_ = spec.bodies;
  for (RigidBody& body : fluid_bodies_) body.contact = ContactKind::kSmooth;
  node_porous_.assign(NodeCount(grid_), 0);
  for (std::size_t b = 0; b < ph.drained.size(); ++b) {
    const auto along = static_cast<std::uint8_t>(1 << ph.drained[b].axis);
    for (std::int32_t node : drained_nodes_[b]) node_porous_[node] |= along;
  }
  return absl::OkStatus();
}

absl::Status TwoPhaseSolver::ValidateInitialPoints(const MaterialPoints& points) const {
  for (std::size_t p = 0; p < points.size(); ++p) {
    if (!(points.porosity0[p] > 0.0 && points.porosity0[p] < 1.0) ||
        !std::isfinite(points.pore_pressure[p])) {
      return Invalid(absl::StrCat("material point ", p),
                     absl::StrCat("porosity ", points.porosity0[p],
                                  " must lie in (0, 1) and the pore pressure be finite"));
    }
  }
  return absl::OkStatus();
}

void TwoPhaseSolver::Prepare() {
  Solver::Prepare();
  const int nodes = NodeCount(grid_);
  for (auto* v : {&node_fluid_velocity_, &node_fluid_force_, &node_fluid_velocity_new_}) {
    v->resize(nodes);
  }
  for (auto* v : {&node_fluid_mass_, &node_drag_, &node_pressure_, &pressure_fixed_, &node_base_,
                  &node_delta_, &node_volume_, &node_domain_, &node_soil_}) {
    v->resize(nodes);
  }
  node_pressure_last_.resize(nodes, std::numeric_limits<double>::quiet_NaN());
  fluid_fixed_.resize(nodes);
}

double TwoPhaseSolver::MixtureMass() const {
  double m = 0.0;
  for (std::size_t p = 0; p < points_.size(); ++p) {
    m += points_.mass[p];
    m += Porosity(p) * phases_.fluid_density * points_.volume[p];
  }
  return m;
}

absl::Status TwoPhaseSolver::Step() {
  RETURN_IF_ERROR(CheckReady());
  RETURN_IF_ERROR(EvaluateShapes());  // N_I, ∇N_I at the step's start; the faces near bodies
  FindFluidContacts();
  RETURN_IF_ERROR(MapToGrid());  // (1) m_α,I, v_α,I^n (eqs. 29–30); p^n at the nodes
  ConstrainStart();              // walls and bodies on v_s^n, then on v_f^n
  ConstrainFluid(node_fluid_velocity_, time_, solver_.pic_fraction);
  // (2) ∇u_p = Δt Σ_I ∇N_I v_s,I (eq. 31) to the model, σ' back (eq. 26);
  // the volumes (eq. 35).
  RETURN_IF_ERROR(UpdateStress());
  RETURN_IF_ERROR(CheckPorosity());
  RETURN_IF_ERROR(ComputeNodalForces());  // (3) F, F_f (eqs. 16d–g), drag (16c, k of eq. 28)
  SolveIntermediateVelocities();          // (4) v_s*, v_f* (eq. 15)
  ConstrainNewVelocities();
  DrainThroughWalls(node_fluid_velocity_, node_velocity_new_);
  RETURN_IF_ERROR(SolvePressure());  // (5) p^{n+1} (eq. 17)
  CorrectVelocities();               // (6) v_s^{n+1}, v_f^{n+1} (eq. 19)
  ConstrainNewVelocities();
  // Without drag in the correction (kIncremental) the phases' changes are
  // independent and the 2×2 solve's water is already right.
  if (!incremental()) DrainThroughWalls(node_fluid_velocity_star_, node_fluid_velocity_star_);
  MapToPoints();  // (7) v_α,p, x_p (eqs. 33–34), p_p from the nodes' p^{n+1}
  return FinishStep();
}

void TwoPhaseSolver::FindFluidContacts() {
  const MaterialPoints& mp = points_;
  fluid_contacts_ = contacts_;
  for (SurfaceContact& contact : fluid_contacts_) {
    const std::size_t p = contact.point;
    contact.mass_floor = kContactMassFloor * Porosity(p) * phases_.fluid_density * mp.volume[p];
  }
}

absl::Status TwoPhaseSolver::MapToGrid() {
  const MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const int nodes = NodeCount(grid_);
  const double rho_f = phases_.fluid_density;
  std::fill(node_mass_.begin(), node_mass_.end(), 0.0);
  std::fill(node_fluid_mass_.begin(), node_fluid_mass_.end(), 0.0);
  std::fill(node_velocity_.begin(), node_velocity_.end(), Vector2d::Zero());
  std::fill(node_fluid_velocity_.begin(), node_fluid_velocity_.end(), Vector2d::Zero());
  std::fill(node_volume_.begin(), node_volume_.end(), 0.0);
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    const double fluid_mass = Porosity(p) * rho_f * mp.volume[p];
    for (int k = 0; k < s.count; ++k) {
      const int i = s.node[k];
      const double w = s.weight[k];
      node_mass_[i] += w * mp.mass[p];
      node_velocity_[i] += w * mp.mass[p] * mp.velocity[p];
      node_fluid_mass_[i] += w * fluid_mass;
      node_fluid_velocity_[i] += w * fluid_mass * mp.fluid_velocity[p];
      node_volume_[i] += w * mp.volume[p];
    }
  }
  // p^n of a node: its p^{n+1} of the last step where it was active then
  // (the grid is fixed), else fitted to the points (FitNodalPressure). A
  // plain average mapped afresh every step would bias the nodes at a
  // boundary (an average from one side), and the points, which take their
  // pressure from the nodes, would drift by that bias step after step.
  bool fit = false;
  for (int i = 0; i < nodes; ++i) {
    // Porosity stays > 0 (checked at the start and after every update), so
    // a node with the solids' mass also has the water's.
    if (Active(i)) {
      node_velocity_[i] /= node_mass_[i];
      node_fluid_velocity_[i] /= node_fluid_mass_[i];
      fit = fit || std::isnan(node_pressure_last_[i]);
      node_pressure_[i] = node_pressure_last_[i];
    } else {
      node_velocity_[i].setZero();
      node_fluid_velocity_[i].setZero();
      node_pressure_[i] = 0.0;
    }
  }
  if (fit) RETURN_IF_ERROR(FitNodalPressure());
  return absl::OkStatus();
}

absl::Status TwoPhaseSolver::CheckPorosity() const {
  for (std::size_t p = 0; p < points_.size(); ++p) {
    if (!(Porosity(p) > 0.0)) {
      return absl::FailedPreconditionError(absl::StrCat(
          "material point ", p, " compacted below its solid volume (porosity ", Porosity(p), ")"));
    }
  }
  return absl::OkStatus();
}

absl::Status TwoPhaseSolver::ComputeNodalForces() {
  // The mixture's force from the total stress σ' − p I (p = p^n, or the
  // water at rest's p_r with kStabilised), gravity on both phases and the
  // tractions; the fluid's Σ n p ∇S V and its weight. (4) solves with them
  // R_s = M_s v_s + Δt (F_mixture − F_fluid), R_f = M_f v_f + Δt F_fluid.
  const MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const int nodes = NodeCount(grid_);
  const double rho_f = phases_.fluid_density;
  const bool incremental = this->incremental();
  std::fill(node_drag_.begin(), node_drag_.end(), 0.0);
  const Vector2d body = BodyAcceleration();
  for (int i = 0; i < nodes; ++i) {
    node_force_[i] = (node_mass_[i] + node_fluid_mass_[i]) * body;
    node_fluid_force_[i] = node_fluid_mass_[i] * body;
  }
  // F-bar: the effective mean stress averaged as the volume change was.
  const std::vector<Matrix2d> effective = ForceStresses();
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    const double porosity = Porosity(p), v = mp.volume[p];
    // kIncremental: p^n; kStabilised: the water at rest's p_r.
    const double pressure = incremental ? mp.pore_pressure[p] : RestPressure(mp.position[p].y());
    const Matrix2d total_v = (effective[p] - pressure * Matrix2d::Identity()) * v;
    const double drag_v = dt_ * DarcyDrag(porosity, rho_f, Permeability(p)) * v;
    for (int k = 0; k < s.count; ++k) {
      const int i = s.node[k];
      node_force_[i] -= total_v * s.gradient[k];
      node_fluid_force_[i] += (porosity * pressure * v) * s.gradient[k];
      node_drag_[i] += s.weight[k] * drag_v;
    }
  }
  return AddLoadForces();
}

void TwoPhaseSolver::SolveIntermediateVelocities() {
  const int nodes = NodeCount(grid_);
  for (int i = 0; i < nodes; ++i) {
    if (!Active(i)) {
      node_velocity_new_[i].setZero();
      node_fluid_velocity_new_[i].setZero();
      continue;
    }
    const Vector2d rs =
        node_mass_[i] * node_velocity_[i] + dt_ * (node_force_[i] - node_fluid_force_[i]);
    const Vector2d rf = node_fluid_mass_[i] * node_fluid_velocity_[i] + dt_ * node_fluid_force_[i];
    const PhaseVelocities v =
        IntermediateVelocities(node_mass_[i], node_fluid_mass_[i], node_drag_[i], rs, rf);
    node_velocity_new_[i] = v.solid;
    node_fluid_velocity_new_[i] = v.fluid;
  }
}

void TwoPhaseSolver::ConstrainNewVelocities() {
  Constrain(node_velocity_new_, time_ + dt_, 1.0);
  ConstrainFluid(node_fluid_velocity_new_, time_ + dt_, 1.0);
}

absl::Status TwoPhaseSolver::SolvePressure() {
  // For δ = p^{n+1} − b, b = p^n (kIncremental) or p_r (kStabilised):
  // Σ_J L_IJ δ_J = −(1/Δt) Σ_p S_Ip V_p [(1 − n)∇·v_s* + n ∇·v_f*]_p,
  // L_IJ = Σ_p mobility_p ∇S_Ip·∇S_Jp V_p (eq. 18a; kStabilised: the drag
  // in the mobility); drained nodes hold their pressure, every other face
  // is impermeable. node_delta_ holds δ (Pa), node_base_ b.
  const MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const int nodes = NodeCount(grid_);
  const double rho_f = phases_.fluid_density;
  const bool incremental = this->incremental();
  FindDrainedNodes();
  std::vector<int> unknown(nodes, -1);
  int count = 0;
  for (int i = 0; i < nodes; ++i) {
    if (Active(i) && std::isnan(pressure_fixed_[i])) {
      unknown[i] = count++;
    }
  }
  for (int i = 0; i < nodes; ++i) {
    // A drained node's p^n at the start is taken as its prescribed value,
    // as the fitted one carries the fit's error at a boundary.
    if (incremental && !std::isnan(pressure_fixed_[i]) && std::isnan(node_pressure_last_[i])) {
      node_pressure_[i] = pressure_fixed_[i];
    }
    node_base_[i] = incremental ? node_pressure_[i] : NodeRest(i);
    node_delta_[i] = std::isnan(pressure_fixed_[i]) ? 0.0 : pressure_fixed_[i] - node_base_[i];
  }
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(count);
  std::vector<Eigen::Triplet<double>> entries;
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    const double porosity = Porosity(p), v = mp.volume[p];
    const double rho_s = mp.mass[p] / ((1.0 - mp.porosity0[p]) * mp.volume0[p]);  // grains, kg/m³
    const double drag_dt =
        incremental ? 0.0 : dt_ * DarcyDrag(porosity, rho_f, Permeability(p));  // kg/m³
    const double mobility = PressureMobility(porosity, rho_s, rho_f, drag_dt) * v;
    double divergence = 0.0;  // (1 − n)∇·v_s* + n ∇·v_f*, 1/s
    for (int k = 0; k < s.count; ++k) {
      divergence += s.gradient[k].dot((1.0 - porosity) * node_velocity_new_[s.node[k]] +
                                      porosity * node_fluid_velocity_new_[s.node[k]]);
    }
    for (int a = 0; a < s.count; ++a) {
      const int row = unknown[s.node[a]];
      if (row < 0) continue;
      rhs[row] -= s.weight[a] * v * divergence / dt_;
      for (int b = 0; b < s.count; ++b) {
        const double l = mobility * s.gradient[a].dot(s.gradient[b]);
        const int col = unknown[s.node[b]];
        if (col >= 0) {
          entries.emplace_back(row, col, l);
        } else {
          rhs[row] -= l * node_delta_[s.node[b]];  // a drained neighbour
        }
      }
    }
  }
  if (count > 0) {
    Eigen::SparseMatrix<double> laplacian(count, count);
    laplacian.setFromTriplets(entries.begin(), entries.end());
    ASSIGN_OR_RETURN(const Eigen::VectorXd solved,
                     SolveSpd(laplacian, rhs, "the pore-pressure solve",
                              "is every part of the soil connected to a drained boundary?",
                              &pressure_iterations_));
    for (int i = 0; i < nodes; ++i) {
      if (unknown[i] >= 0) node_delta_[i] = solved[unknown[i]];
    }
  }
  return absl::OkStatus();
}

void TwoPhaseSolver::CorrectVelocities() {
  // M_s Δv_s = F_s + D (Δv_f − Δv_s), M_f Δv_f = F_f − D (Δv_f − Δv_s),
  // F_α = −Δt Σ_p φ_α S_Ip V_p ∇δ_p, φ_s = 1 − n, φ_f = n; D = 0
  // (kIncremental, the paper's) or the drag of (4) (kStabilised).
  const MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const int nodes = NodeCount(grid_);
  const bool incremental = this->incremental();
  std::fill(node_force_.begin(), node_force_.end(), Vector2d::Zero());
  std::fill(node_fluid_force_.begin(), node_fluid_force_.end(), Vector2d::Zero());
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    Vector2d grad = Vector2d::Zero();  // ∇δ at the point, Pa/m
    for (int k = 0; k < s.count; ++k) grad += node_delta_[s.node[k]] * s.gradient[k];
    const double porosity = Porosity(p), v = mp.volume[p];
    for (int k = 0; k < s.count; ++k) {
      node_force_[s.node[k]] -= (s.weight[k] * (1.0 - porosity) * v) * grad;
      node_fluid_force_[s.node[k]] -= (s.weight[k] * porosity * v) * grad;
    }
  }
  // The corrected water drags on its own change only where a porous wall
  // holds the solids (DrainThroughWalls): kStabilised needs v_f* for that.
  if (!incremental) node_fluid_velocity_star_ = node_fluid_velocity_new_;
  for (int i = 0; i < nodes; ++i) {
    if (!Active(i)) continue;
    const PhaseVelocities dv = IntermediateVelocities(
        node_mass_[i], node_fluid_mass_[i], incremental ? 0.0 : node_drag_[i], dt_ * node_force_[i],
        dt_ * node_fluid_force_[i]);
    node_velocity_new_[i] += dv.solid;
    node_fluid_velocity_new_[i] += dv.fluid;
  }
}

void TwoPhaseSolver::MapToPoints() {
  // Both phases' velocities (PIC fraction α), the position with the
  // solid's. The pore pressure is interpolated from the nodes' p^{n+1}
  // rather than incremented (eq. 32): a point then sees a drained node's
  // value at once, also where a free surface opens (a gate removed), where
  // an increment would leave it its old pressure.
  MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const int nodes = NodeCount(grid_);
  const double alpha = solver_.pic_fraction;
  for (int i = 0; i < nodes; ++i) {
    node_pressure_last_[i] =
        Active(i) ? node_base_[i] + node_delta_[i] : std::numeric_limits<double>::quiet_NaN();
  }
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    Vector2d vs = Vector2d::Zero(), dvs = Vector2d::Zero();
    Vector2d vf = Vector2d::Zero(), dvf = Vector2d::Zero();
    double pressure = 0.0, weight = 0.0;  // Pa, [-]
    for (int k = 0; k < s.count; ++k) {
      const int i = s.node[k];
      const double w = s.weight[k];
      vs += w * node_velocity_new_[i];
      dvs += w * (node_velocity_new_[i] - node_velocity_[i]);
      vf += w * node_fluid_velocity_new_[i];
      dvf += w * (node_fluid_velocity_new_[i] - node_fluid_velocity_[i]);
      if (!std::isnan(node_pressure_last_[i])) {  // a node too light to be active: left out
        pressure += w * node_pressure_last_[i];
        weight += w;
      }
    }
    mp.position[p] = KeepOffWalls(mp.position[p], mp.position[p] + dt_ * vs);
    mp.velocity[p] = alpha * vs + (1.0 - alpha) * (mp.velocity[p] + dvs);
    mp.fluid_velocity[p] = alpha * vf + (1.0 - alpha) * (mp.fluid_velocity[p] + dvf);
    mp.pore_pressure[p] = weight > 0.0 ? pressure / weight : mp.pore_pressure[p];
  }
}

double TwoPhaseSolver::RestPressure(double y) const {
  return HydrostaticPressure(phases_.fluid_density, solver_.gravity.norm(), phases_.water_table, y);
}

double TwoPhaseSolver::NodeRest(int node) const {
  return RestPressure(NodePosition(grid_, node).y());
}

void TwoPhaseSolver::ConstrainFluid(std::vector<Vector2d>& velocity, double wall_time,
                                    double weight) {
  std::fill(fluid_fixed_.begin(), fluid_fixed_.end(), std::uint8_t{0});
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    if (walls_[w].remove_time <= time_) continue;
    const int axis = walls_[w].axis;
    // Impermeable: the water's normal velocity is the wall's.
    const double normal = WallVelocity(walls_[w], wall_time)[axis];
    for (std::int32_t node : wall_nodes_[w]) {
      if (node_porous_[node] & (1 << axis)) continue;  // a drained line along the wall
      if (node_mass_[node] > min_node_mass_) {
        impulse_[w][axis] += weight * node_fluid_mass_[node] * (normal - velocity[node][axis]);
      }
      velocity[node][axis] = normal;
      fluid_fixed_[node] |= static_cast<std::uint8_t>(1 << axis);
    }
  }
  ResolveBodies(fluid_contacts_, fluid_bodies_,
                {node_fluid_mass_, velocity, fluid_fixed_, min_node_mass_}, wall_time, weight);
}

void TwoPhaseSolver::FindDrainedNodes() {
  std::fill(pressure_fixed_.begin(), pressure_fixed_.end(), kFree);
  const int nx = grid_.nx + 1, ny = grid_.ny + 1;
  // A node's share of soil: Σ_p S_Ip V_p over the part of its volume h²·t
  // that lies inside the domain, [-] (1 inside the soil, ½ on a flat free
  // face, ¼ at a free corner). A wall or the grid's edge bounds the domain:
  // a node on it has half its volume (a quarter in a corner of two), so the
  // soil along a wall is no free surface (the wall is impermeable).
  const double full = grid_.cell_size * grid_.cell_size * solver_.thickness;
  std::fill(node_domain_.begin(), node_domain_.end(), 1.0);
  for (int i = 0; i < nx; ++i) {
    for (int j : {0, ny - 1}) node_domain_[j * nx + i] *= 0.5;
  }
  for (int j = 0; j < ny; ++j) {
    for (int i : {0, nx - 1}) node_domain_[j * nx + i] *= 0.5;
  }
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    const int last_line = walls_[w].axis == 0 ? grid_.nx : grid_.ny;
    // Walls on the grid's edge are counted there already.
    if (walls_[w].remove_time <= time_ || wall_lines_[w] == 0 || wall_lines_[w] == last_line) {
      continue;
    }
    for (std::int32_t node : wall_nodes_[w]) node_domain_[node] *= 0.5;
  }
  // Soil pressed against a body is no free surface either (bodies are
  // impermeable): the body's share of a node counts as filled.
  const Vector2d lower = grid_.origin;
  const Vector2d upper = grid_.origin + grid_.cell_size * Vector2d(grid_.nx, grid_.ny);
  std::vector<Vector2d> centers(bodies_.size());  // m, now
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    centers[b] = bodies_[b].center + DisplacementAt(bodies_[b].velocity, time_);
  }
  std::vector<double>& fraction = node_soil_;
  std::fill(fraction.begin(), fraction.end(), 0.0);
  for (int node = 0; node < nx * ny; ++node) {
    if (!(node_mass_[node] > min_node_mass_)) continue;
    double filled = node_volume_[node];  // m³
    for (std::size_t b = 0; b < bodies_.size(); ++b) {
      filled += full * BodyShareOfNode(bodies_[b], centers[b], NodePosition(grid_, node),
                                       grid_.cell_size, lower, upper);
    }
    fraction[node] = filled / (full * node_domain_[node]);
  }
  // Whether the step (di, dj) from node (i, j) leaves a standing wall's line
  // or crosses it: beyond a wall lies no free surface, only the edge of a
  // point's domain.
  const auto walled = [&](int i, int j, int di, int dj) {
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      if (walls_[w].remove_time <= time_) continue;
      const int at = walls_[w].axis == 0 ? i : j, step = walls_[w].axis == 0 ? di : dj;
      const int line = wall_lines_[w];
      if (step != 0 && (at == line || (at - line) * (at + step - line) < 0)) return true;
    }
    return false;
  };
  // Whether one of the 8 nodes around `node`, not walled off, has mass but
  // less than kLightNeighbourFraction of soil.
  const auto beside_a_light_node = [&](int node) {
    const int i = node % nx, j = node / nx;
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        const int q = node + dj * nx + di;
        if ((di != 0 || dj != 0) && i + di >= 0 && i + di < nx && j + dj >= 0 && j + dj < ny &&
            node_mass_[q] > min_node_mass_ && fraction[q] < kLightNeighbourFraction &&
            !walled(i, j, di, dj)) {
          return true;
        }
      }
    }
    return false;
  };
  for (int node = 0; node < nx * ny; ++node) {
    if (!(node_mass_[node] > min_node_mass_)) continue;
    if (phases_.drained_free_surface &&
        (fraction[node] < kSurfaceFraction ||
         (phases_.free_surface_beside_light_nodes && beside_a_light_node(node)))) {
      pressure_fixed_[node] = 0.0;  // on the free surface (or outside it)
    } else if (fraction[node] < kEmptyFraction) {
      // A node that only the edge of a point's domain reaches (a face that
      // just moved into a new cell) barely takes part in the pressure
      // equation: its pressure is held, not solved for.
      pressure_fixed_[node] = node_pressure_[node];
    }
  }
  for (std::size_t b = 0; b < drained_nodes_.size(); ++b) {
    for (std::int32_t node : drained_nodes_[b]) {
      if (node_mass_[node] > min_node_mass_) pressure_fixed_[node] = phases_.drained[b].pressure;
    }
  }
}

void TwoPhaseSolver::DrainThroughWalls(const std::vector<Vector2d>& start,
                                       const std::vector<Vector2d>& pull) {
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    if (walls_[w].remove_time <= time_) continue;
    const int axis = walls_[w].axis;
    const auto bit = static_cast<std::uint8_t>(1 << axis);
    for (std::int32_t node : wall_nodes_[w]) {
      if (!(node_mass_[node] > min_node_mass_) || !(node_porous_[node] & bit) ||
          !(node_fixed_[node] & bit)) {
        continue;
      }
      const double m = node_fluid_mass_[node], d = node_drag_[node];  // kg
      const double v =
          (m * start[node][axis] + dt_ * node_fluid_force_[node][axis] + d * pull[node][axis]) /
          (m + d);
      // The difference goes through the held solids into the wall.
      impulse_[w][axis] += m * (v - node_fluid_velocity_new_[node][axis]);
      node_fluid_velocity_new_[node][axis] = v;
    }
  }
}

absl::Status TwoPhaseSolver::FitNodalPressure() {
  // Least squares: the nodal p_I whose interpolation Σ_I S_Ip p_I best
  // matches the points' p_p, weighted by volume: (Σ_p V_p S_Ip S_Jp) p_J =
  // Σ_p V_p S_Ip p_p. Exact for any field the shape functions can represent
  // (a hydrostatic pressure is linear), where an average is not at a
  // boundary. A small multiple of the lumped diagonal keeps a node that only
  // the edge of a point's domain reaches well-posed.
  const MaterialPoints& mp = points_;
  const int nodes = NodeCount(grid_);
  std::vector<int> index(nodes, -1);
  int count = 0;
  for (int i = 0; i < nodes; ++i) {
    if (node_mass_[i] > min_node_mass_) index[i] = count++;
  }
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(count);
  for (std::size_t p = 0; p < mp.size(); ++p) {
    const ShapeValues& s = shape_[p];
    for (int a = 0; a < s.count; ++a) {
      const int row = index[s.node[a]];
      if (row < 0) continue;
      rhs[row] += mp.volume[p] * s.weight[a] * mp.pore_pressure[p];
      entries.emplace_back(row, row, kFitRegularisation * mp.volume[p] * s.weight[a]);
      for (int b = 0; b < s.count; ++b) {
        const int col = index[s.node[b]];
        if (col >= 0) entries.emplace_back(row, col, mp.volume[p] * s.weight[a] * s.weight[b]);
      }
    }
  }
  Eigen::SparseMatrix<double> m(count, count);
  m.setFromTriplets(entries.begin(), entries.end());
  ASSIGN_OR_RETURN(const Eigen::VectorXd fitted,
                   SolveSpd(m, rhs, "the fit of the nodal pore pressure"));
  for (int i = 0; i < nodes; ++i) {
    if (index[i] >= 0 && std::isnan(node_pressure_[i])) node_pressure_[i] = fitted[index[i]];
  }
  return absl::OkStatus();
}

}  // namespace rvehub::mpm
