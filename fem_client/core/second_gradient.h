// The local second-gradient regularisation of Desrues et al. §4 (after
// Chambon, Caillerie & Matsushima 2001): the body is a microstructured
// continuum whose micro-kinematic field v_ij is tied to the displacement
// gradient ∂u_i/∂x_j by Lagrange multipliers λ_ij (eqs. 41, 43), and whose
// double stress Σ_ijk answers ∂v_ij/∂x_k through one modulus D (eq. 44).
// The RVEs keep giving σ from ΔF alone; Σ adds an internal length of order
// √(D/|H|) (H the softening modulus), so a shear band stops shrinking with
// the mesh.
//
// The element is the usual one for it: Q8R (8-node serendipity for u, 2×2
// Gauss points), v bilinear on the four corners, λ constant per element.
// Boundary double forces are zero (eq. 39): no condition on v.
//
// Updated Lagrangian, as the solver (assembly.h): over a load step the
// unknowns are the increments Δu, Δv, Δλ; the second-gradient terms are
// integrated on the step's configuration X, where the constraint reads
// Δv_ij = ∂Δu_i/∂X_j, and Σ = Σ₀ + D : ∂Δv/∂X (Σ₀ committed). The
// Jaumann terms of eq. 45 (Σ's rotation with the spin) are left out: Σ is
// a regulariser whose size, not its orientation, sets the band width.
// Per load step the terms are linear in the increments, so after each
// solve their own equations hold exactly.
//
// Index conventions: v_ij and λ_ij at 2i + j; Σ_ijk and ∂v_ij/∂x_k at
// 4i + 2j + k (eq. 44's order).
#ifndef RVEHUB_FEM_CLIENT_CORE_SECOND_GRADIENT_H_
#define RVEHUB_FEM_CLIENT_CORE_SECOND_GRADIENT_H_

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "fem_client/core/element.h"
#include "fem_client/core/mesh.h"

namespace rvehub::fem {

using DoubleStress = Eigen::Matrix<double, 8, 1>;  // Σ_ijk, N/m (Pa·m)
using SecondGradientModulus = Eigen::Matrix<double, 8, 8>;

// Desrues eq. 44: ∇Σ = M ∂v̇/∂x with the one parameter D, N (Pa·m², per
// metre of thickness).
SecondGradientModulus IsotropicSecondGradientModulus(double d);

// What the second gradient adds to the solver's state: committed values.
struct SecondGradientState {
  std::vector<DoubleStress> double_stress;  // per Gauss point, N/m
  Eigen::VectorXd multiplier;               // λ, 4 per element, Pa
  Eigen::VectorXd micro;                    // v since the start, 4 per corner node, [-]
};

// The extra unknowns, numbered after the displacements' own: first Δv, 4
// per corner node (in node order), then Δλ, 4 per element.
class SecondGradient {
 public:
  // InvalidArgument unless every element is Q8R, or for D not positive and
  // finite.
  static absl::StatusOr<SecondGradient> Create(const Mesh& mesh, double modulus);

  int unknowns() const { return 4 * corner_nodes_ + 4 * elements_; }
  int corner_nodes() const { return corner_nodes_; }
  // The unknown of v_c (c = 2i + j) at a corner node, of λ_c of an element.
  int MicroUnknown(int node, int c) const { return 4 * corner_[node] + c; }
  int MultiplierUnknown(int element, int c) const { return 4 * (corner_nodes_ + element) + c; }

  // The state before the first step: everything zero.
  SecondGradientState Initial() const;

  struct Terms {
    // −∫ λ_ij ∂δu_i/∂X_j dV: λ's share of the internal forces, 2 per node, N/m.
    Eigen::VectorXd internal;
    // The extra unknowns' residual: ∫ (Σ_ijk ∂δv_ij/∂X_k + λ_ij δv_ij) dV
    // (N/m per unit v) and ∫ δλ_ij (∂Δu_i/∂X_j − Δv_ij) dV (m² per unit λ).
    Eigen::VectorXd residual;
    std::vector<DoubleStress> double_stress;  // at the increments, per Gauss point
  };
  // The terms at the increments du (2 per node, m) and ds (the extra
  // unknowns) from `committed`, on the node positions X of the step's start.
  Terms Evaluate(const Mesh& mesh, std::span<const Eigen::Vector2d> x,
                 const SecondGradientState& committed, const Eigen::VectorXd& du,
                 const Eigen::VectorXd& ds) const;

  // ∂(internal, residual)/∂(du, ds) on X: a (2·nodes + unknowns)² matrix
  // with the displacement rows and columns first and no uu block (the RVEs'
  // part is the solver's). Constant over a load step.
  Eigen::SparseMatrix<double> Stiffness(const Mesh& mesh, std::span<const Eigen::Vector2d> x) const;

  // The committed state after a converged step with increments ds and
  // `double_stress` (Evaluate's at them).
  SecondGradientState Advance(const SecondGradientState& committed, const Eigen::VectorXd& ds,
                              std::vector<DoubleStress> double_stress) const;

 private:
  SecondGradient(std::vector<int> corner, int corner_nodes, int elements, double modulus)
      : corner_(std::move(corner)),
        corner_nodes_(corner_nodes),
        elements_(elements),
        modulus_(IsotropicSecondGradientModulus(modulus)) {}

  std::vector<int> corner_;  // per mesh node: its corner index, −1 for a midside
  int corner_nodes_ = 0;
  int elements_ = 0;
  SecondGradientModulus modulus_;
};

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_SECOND_GRADIENT_H_
