// Contact of the soil with rigid bodies (footings, pipes, platens) at the
// soil's surface, not at the grid nodes inside the body.
//
// Each material point near a body has a face towards it: its material
// reaches the distance `extent` along the body's normal (DomainExtent). The
// contact constraint is that the soil's velocity interpolated at that face
// (linear weights, over the nodes that carry mass) does not approach the body
// faster than the gap between them closes in one step ("speculative"
// contact, so that a face meets the body's surface exactly instead of a node
// row early or late). The face's velocity is the point's own (see
// SurfaceContact). The impulses that enforce it, each one's normal part
// compressive and its tangential part bounded by Coulomb's μ times the normal
// one (rough: unbounded while pressing; smooth: none), are found by projected
// Gauss–Seidel sweeps over the contacts in a fixed order (the sequential
// impulses of rigid-body dynamics, Catto 2005; on an MPM grid cf. the
// multi-velocity-field contact of Bardenhagen et al. 2001 with a rigid body
// as one field, and the gap criterion of Huang et al. 2011). A body pushing a
// soil surface that lies between node rows thus moves that surface with it,
// and the soil can separate from it (unilateral).
#ifndef RVEHUB_MPM_CLIENT_CORE_BODY_CONTACT_H_
#define RVEHUB_MPM_CLIENT_CORE_BODY_CONTACT_H_

#include <Eigen/Dense>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "mpm_client/core/model.h"
#include "mpm_client/core/shape.h"

namespace rvehub::mpm {

// Where a material point's face is relative to a body.
struct BodyGap {
  double gap = 0.0;  // m: clearance between the face and the body; < 0: overlap
  Eigen::Vector2d normal = Eigen::Vector2d::UnitY();  // unit, from the body into the soil
  Eigen::Vector2d face = Eigen::Vector2d::Zero();     // m, the point's face, x − extent·n
};

// How far a point's material reaches from its centre along the unit vector
// n, m: the support of the ellipse through the midpoints of its four faces,
// x ± F e_i·lp0_i (lp0, m: its initial GIMP half-sizes), that is the image
// under F of the circle inscribed in its initial box:
// √((n·F e_x·lp0_x)² + (n·F e_y·lp0_y)²). On a face the midpoint is exact
// (a rough platen over a barrelling row of points meets its material there);
// off a corner it is the mean surface of a staircase of boxes, not the
// corner's tip. Not the stretched box lp0_i·|F e_i| that the shape functions
// use: under shear that box grows along both axes while the material only
// slants (simple shear γ = 3 gives it 3.2 times the reach normal to the
// shear plane), and a contact found with it acts on a point whose material
// is still up to a cell from the body.
double DomainExtent(const Eigen::Matrix2d& f, const Eigen::Vector2d& lp0, const Eigen::Vector2d& n);

// The half-sizes of a box that holds the point's material, m: |F|·lp0, the
// bound of the parallelogram F·[−lp0, lp0]² (a broad phase for contacts).
Eigen::Vector2d DomainBound(const Eigen::Matrix2d& f, const Eigen::Vector2d& lp0);

// The gap of a point at x, its initial GIMP half-sizes lp0 (m) carried by
// the deformation gradient f, to `body` centred at `center`: the signed
// distance from x to the body's surface (outside +; inside, to the nearest
// face), less DomainExtent along the normal (with f = I, the initial box's
// inscribed ellipse: √((n_x·lp0_x)² + (n_y·lp0_y)²)).
BodyGap GapToBody(const RigidBody& body, const Eigen::Vector2d& center, const Eigen::Vector2d& x,
                  const Eigen::Matrix2d& f, const Eigen::Vector2d& lp0);

// How far past a rectangle body's corners the contact may push the soil,
// m: where soil faces one of the body's faces within a cell h (m) of it at
// a corner (a point's box, position ± half_size, reaches that corner), the
// distance from the corner to the next node line beyond it, on a grid of
// cells h from `origin`. The grid moves a cell as a whole: a footing whose
// edge crosses a cell drags the soil on that cell's far side down with it
// (1 point per cell: the point under the edge is pushed over its whole
// width, h/2 beyond a mid-cell edge). 0 when every such corner is on a node
// line, and for circles.
double CornerOverhang(const RigidBody& body, const Eigen::Vector2d& center,
                      std::span<const Eigen::Vector2d> position,
                      std::span<const Eigen::Vector2d> half_size, const Eigen::Vector2d& origin,
                      double h);

// The share of a grid node's volume that `body` (centred at `center`)
// fills, [-]: ∫ N(x) χ_body(x) dA / h² over the part of the node's support
// inside the grid [lower, upper] (m), N the bilinear hat of the node at
// `node` on cells of size h (m). The same measure as the soil's share Σ_p
// S_Ip V_p / (h² t) of a saturated step's free-surface test, so that soil
// pressed against an impermeable body is no free surface: ½ on a flat face
// through the node, ¼ at a convex corner, the hat's whole in-grid integral
// deep inside. Rectangles exactly (the hat is separable); circles by a
// 16 × 16 midpoint rule on the support where the surface crosses it.
double BodyShareOfNode(const RigidBody& body, const Eigen::Vector2d& center,
                       const Eigen::Vector2d& node, double h, const Eigen::Vector2d& lower,
                       const Eigen::Vector2d& upper);

// One point's face near one body, found at the step's start. The face moves
// as the point's own affine motion carries it: v_face = v_p + L_p·(x_face −
// x_p) = Σ_I c_I v_I with c_I = S_Ip + ∇S_Ip·(x_face − x_p) over the point's
// nodes (Σ c_I = 1; some c_I may be negative). Constraining that velocity,
// not a field interpolated at the face, keeps the point itself out of the
// body (a GIMP point straddling cells moves with nodes the face's own cell
// lacks).
struct SurfaceContact {
  std::int32_t body = 0;  // index into the case's bodies
  std::int32_t point = 0;
  BodyGap where;
  int count = 0;                                    // the point's grid nodes
  std::array<std::int32_t, kMaxShapeNodes> node{};  // their indices
  std::array<double, kMaxShapeNodes> weight{};      // c_I, [-]
  // The impulse moves node k as if its mass were at least this, kg: a
  // fraction kContactMassFloor of the point's own. At the far tail of a GIMP
  // point's support the node's mass is ~S² while its weight c is ~S^½, so a
  // plain share would set that nearly empty node flying, and the point's
  // velocity gradient with it.
  double mass_floor = 0.0;
};

inline constexpr double kContactMassFloor = 0.1;

// The grid the contacts act on: nodal masses (kg) and velocities (m/s);
// fixed[i] bit 0 / bit 1: node i's x / y velocity is held by a wall (the
// contacts leave it alone).
struct ContactGrid {
  std::span<const double> mass;
  std::span<Eigen::Vector2d> velocity;
  std::span<const std::uint8_t> fixed;
  double min_mass = 0.0;  // kg, lighter nodes carry no soil
};

// Sweeps of the projected Gauss–Seidel solve at most, and its stop: the
// largest velocity change of a sweep, m/s.
inline constexpr int kContactMaxSweeps = 200;
inline constexpr double kContactTolerance = 1e-12;

// Enforces the contacts on the nodal velocities over a step dt (s), each
// body moving at body_velocity[b] (m/s). Adds weight × the momentum each
// body gave the soil (N·s) to impulse[b]. Deterministic: contacts in the
// given order, a bounded number of sweeps. Returns the sweeps done.
int ResolveContacts(std::span<const SurfaceContact> contacts, std::span<const RigidBody> bodies,
                    std::span<const Eigen::Vector2d> body_velocity, double dt, double weight,
                    ContactGrid grid, std::span<Eigen::Vector2d> impulse);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_BODY_CONTACT_H_
