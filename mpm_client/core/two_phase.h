// Kernels of the saturated (two-phase, u–v–p) MPM step after
// liang-zhao-wu-soga-2023 §2.2–3: small stateless functions, SI units.
// Grains and fluid are incompressible; p is the pore pressure, compression
// positive, and the total stress is σ' − p·I (tension +).
#ifndef RVEHUB_MPM_CLIENT_CORE_TWO_PHASE_H_
#define RVEHUB_MPM_CLIENT_CORE_TWO_PHASE_H_

#include <Eigen/Dense>
#include <cmath>
#include <vector>

namespace rvehub::mpm {

// g in Darcy's law, where a permeability k (m/s, hydraulic conductivity)
// means k = κ·ρ_f·g/μ: m/s², whatever the case's body force.
inline constexpr double kDarcyGravity = 9.81;

// Porosity of a point whose volume is J times its initial one, the grains
// incompressible: n = 1 − (1 − n0)/J, [-].
inline double PorosityAt(double n0, double volume_ratio) { return 1.0 - (1.0 - n0) / volume_ratio; }

// Pore pressure of water at rest, ρ_f·g·(y_w − y) below the water table
// y_w and 0 above it or without one (y_w = +∞): Pa, compression +.
inline double HydrostaticPressure(double fluid_density, double gravity, double water_table,
                                  double y) {
  const double depth = water_table - y;  // m
  return std::isfinite(depth) && depth > 0.0 ? fluid_density * gravity * depth : 0.0;
}

// The material's top surface over a grid's columns of cells, from its
// points: what "water at rest" means once a flow has moved the surface (the
// water filling the material to its top, at rest under gravity). Column i
// spans x0 + i·h ≤ x < x0 + (i + 1)·h; its height is the highest top edge of
// the points centred in it, m.
class SurfaceProfile {
 public:
  // nx columns of width h (m) from x0 (m), none with points yet.
  SurfaceProfile(double x0, double h, int nx);
  // A point centred at x (m) whose top edge is at `top` (m). Points outside
  // the columns count toward the nearest edge column.
  void Add(double x, double top);
  // The surface's height at x, m: the column heights interpolated linearly
  // between column centres, held flat toward a column without points and
  // beyond the edge columns' centres; −∞ when x's own column has none.
  double HeightAt(double x) const;

 private:
  int Column(double x) const;

  double x0_, h_;
  std::vector<double> top_;  // per column, m; −∞: no point
};

// Void ratio e = n/(1 − n), [-].
inline double VoidRatio(double porosity) { return porosity / (1.0 - porosity); }

// c of k = c·e³/(1 + e) (eq. 28) such that k(e0) = k0: m/s.
inline double KozenyCarmanCoefficient(double e0, double k0) {
  return k0 * (1.0 + e0) / (e0 * e0 * e0);
}

// k = c·e³/(1 + e) (eq. 28), m/s.
inline double KozenyCarmanPermeability(double c, double e) { return c * e * e * e / (1.0 + e); }

// Darcy drag per unit volume of mixture and unit relative velocity,
// n²·ρ_f·g/k (eq. 2): kg/(m³·s).
inline double DarcyDrag(double porosity, double fluid_density, double permeability) {
  return porosity * porosity * fluid_density * kDarcyGravity / permeability;
}

// How fast a pressure gradient accelerates the mixture's volume flux
// (1 − n) v_s + n v_f within one step when the drag D = Δt·n²ρ_f g/k
// (kg/m³) acts implicitly on the same step: m³/kg,
//   [(1 − n)² ρ'_f + n² ρ'_s + D] / [ρ'_s ρ'_f + D (ρ'_s + ρ'_f)],
// ρ'_s = (1 − n) ρ_s, ρ'_f = n ρ_f. Without drag it is eq. 10's
// (1 − n)/ρ_s + n/ρ_f, each phase accelerated on its own; as k → 0 it
// tends to 1/ρ_mixture, the phases locked.
inline double PressureMobility(double porosity, double solid_density, double fluid_density,
                               double drag_dt) {
  const double rs = (1.0 - porosity) * solid_density, rf = porosity * fluid_density;
  return ((1.0 - porosity) * (1.0 - porosity) * rf + porosity * porosity * rs + drag_dt) /
         (rs * rf + drag_dt * (rs + rf));
}

struct PhaseVelocities {
  Eigen::Vector2d solid = Eigen::Vector2d::Zero();  // m/s
  Eigen::Vector2d fluid = Eigen::Vector2d::Zero();  // m/s
};

// The intermediate velocities of one node (lumped eqs. 6 and 8) with the
// drag implicit, so that any permeability is stable at the same Δt:
//   M_s v_s* = R_s + D (v_f* − v_s*),  M_f v_f* = R_f − D (v_f* − v_s*),
// with R_s = M_s v_s + Δt (F_mixture − F_fluid), R_f = M_f v_f + Δt F_fluid
// (kg·m/s) and D = Δt·Σ S_Ip·drag_p·V_p (kg). Solved through the relative
// velocity w = (M_s R_f − M_f R_s)/(M_s M_f + D (M_s + M_f)), which tends to
// 0 as k → 0 (the phases move together) without dividing by small numbers.
inline PhaseVelocities IntermediateVelocities(double solid_mass, double fluid_mass, double drag_dt,
                                              const Eigen::Vector2d& solid_momentum,
                                              const Eigen::Vector2d& fluid_momentum) {
  const Eigen::Vector2d w = (solid_mass * fluid_momentum - fluid_mass * solid_momentum) /
                            (solid_mass * fluid_mass + drag_dt * (solid_mass + fluid_mass));
  return {(solid_momentum + drag_dt * w) / solid_mass, (fluid_momentum - drag_dt * w) / fluid_mass};
}

// Terzaghi's excess pore pressure in a layer of thickness H drained at
// z = 0 and impermeable at z = H, after a sudden load p0 (Pa): the series
// p(z, Tv) = Σ (4 p0/π)/(2m+1)·sin((2m+1)π z/(2H))·exp(−(2m+1)² π² Tv/4),
// Tv = c_v t/H², c_v = k M/(ρ_f g), summed until the terms are below 1e-12 p0.
double TerzaghiExcessPressure(double p0, double z_over_h, double tv);

// The steady pore pressure in a layer of height H (m) drained at its base
// z = 0 and compressed at the strain rate ε̇ (1/s) by an impermeable platen
// at z = H: the water squeezed out of the layer above z flows down through
// it by Darcy's law, so p(z) = ε̇·ρ_f·g·z·(2H − z)/(2k), Pa (k in m/s, g of
// Darcy's law), whatever the skeleton's stiffness. Its mean over the layer
// is ⅔·p(H).
inline double SteadyConstantRateOfStrainPressure(double strain_rate, double height, double z,
                                                 double permeability, double fluid_density) {
  return strain_rate * fluid_density * kDarcyGravity * z * (2.0 * height - z) /
         (2.0 * permeability);
}

// Terzaghi's degree of consolidation U(Tv) = 1 − Σ 8/((2m+1)²π²)·exp(−(2m+1)² π² Tv/4), [-].
double TerzaghiDegreeOfConsolidation(double tv);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_TWO_PHASE_H_
