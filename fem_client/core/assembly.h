// Kinematics and assembly, updated Lagrangian. A load step starts on the
// configuration X (the mesh's committed node positions) and looks for the
// nodal increments Δu; the current configuration is x = X + Δu.
// - Each Gauss point's material gets ΔF = ∂x/∂X = I + ∂Δu/∂X (G&Z eqs.
//   10–11: stretch and rotation together), 3×3 with ΔF_zz = 1.
// - The residual R = ∫ Bᵀσ dv − f_ext (G&Z eq. 4) is integrated on x with
//   the returned Cauchy stress σ; pressures act normal to the current edges.
// - K = ∂R/∂Δu exactly, given D = ∂σ/∂ΔF: the material part ∫ Bᵀ D B dv
//   (G&Z eq. 3), plus the initial-stress part (R depends on x through dv
//   and ∇_x N: without it Newton converges only linearly, at a rate of
//   order |σ|/|D|) and the pressures' load stiffness.
// Node forces are per metre of thickness (N/m), 2 dofs per node (2a + i).
#ifndef RVEHUB_FEM_CLIENT_CORE_ASSEMBLY_H_
#define RVEHUB_FEM_CLIENT_CORE_ASSEMBLY_H_

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "fem_client/core/boundary.h"
#include "fem_client/core/element.h"
#include "fem_client/core/material.h"
#include "fem_client/core/mesh.h"

namespace rvehub::fem {

// Node positions x + du (du: 2 per node), m.
std::vector<Eigen::Vector2d> Moved(std::span<const Eigen::Vector2d> x, const Eigen::VectorXd& du);

// Every Gauss point's geometry at node positions x, element by element; the
// first inverted or degenerate element's InvalidArgument.
absl::StatusOr<std::vector<PointGeometry>> EvaluateGeometry(const Mesh& mesh,
                                                            std::span<const Eigen::Vector2d> x);

// ΔF = I + Σ_a Δu_a ⊗ ∇_X N_a at every Gauss point; `reference`: the
// geometry on X.
std::vector<Eigen::Matrix3d> DeformationIncrements(const Mesh& mesh,
                                                   std::span<const PointGeometry> reference,
                                                   const Eigen::VectorXd& du);

// f_int = ∫ Bᵀσ dv with `current` the geometry on x, N/m.
Eigen::VectorXd InternalForces(const Mesh& mesh, std::span<const PointGeometry> current,
                               std::span<const PointResponse> responses);

// f_ext of the pressures on the edges at node positions x (consistent nodal
// forces: pL/2 at each end of a straight 2-node edge; pL/6, pL/6, 2pL/3 on
// a 3-node one), N/m, size `dofs`.
Eigen::VectorXd PressureForces(int dofs, std::span<const PressureLoad> pressures,
                               std::span<const Eigen::Vector2d> x);

// K = ∂(f_int − f_ext)/∂Δu (see the top of this file), dofs × dofs, N/m².
// `tangents`: D of each Gauss point. Not symmetric in general.
Eigen::SparseMatrix<double> TangentStiffness(const Mesh& mesh,
                                             std::span<const PointGeometry> reference,
                                             std::span<const PointGeometry> current,
                                             std::span<const PointResponse> responses,
                                             std::span<const Tangent> tangents,
                                             std::span<const PressureLoad> pressures,
                                             std::span<const Eigen::Vector2d> x);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_ASSEMBLY_H_
