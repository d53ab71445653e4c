// The sparse symmetric positive-definite solve of the saturated step (the
// pore-pressure Poisson equation and the fit of nodal pore pressures): one
// place for its tolerances and for what its failures say.
#ifndef RVEHUB_MPM_CLIENT_CORE_SPD_SOLVE_H_
#define RVEHUB_MPM_CLIENT_CORE_SPD_SOLVE_H_

#include <Eigen/Sparse>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace rvehub::mpm {

// Relative residual a solve reaches: far below what the step's other
// errors are, and reached in a few dozen iterations on the grids of the cases.
inline constexpr double kSpdTolerance = 1e-12;
// A solve that reaches its iteration limit short of kSpdTolerance is still
// taken below this residual, where 1e-9 of the pressure is far below the
// step's other errors: the nodal fit stalled at 4.4e-12 after 1000
// iterations at 3.09 s of the §4.3 column (a Mohr–Coulomb skeleton with
// free_surface_beside_light_nodes, nearly at rest), a node reached only by a
// point's corner making its matrix badly conditioned.
inline constexpr double kSpdStalledTolerance = 1e-9;

// Solves the symmetric positive-definite system a x = b (same sizes) by
// conjugate gradients to kSpdTolerance, at most max(1000, 4·rows)
// iterations (kSpdStalledTolerance where it stalls there). InternalError
// naming `what`:
// - "... met a value that is not finite in its matrix or right-hand side" or
//   "... met values too large to solve" (a squared norm overflows, and CG
//   with it), then ": the solution became unstable": the step that built
//   the system blew up, and `hint` would mislead, so it is not given;
// - "... broke down (its iterates are not finite: the matrix is singular or
//   not positive definite)" and "... did not converge (N iterations, error
//   E)", each followed by ": `hint`" when a hint (the likely cause) is given.
// `iterations` (optional) gets the count.
absl::StatusOr<Eigen::VectorXd> SolveSpd(const Eigen::SparseMatrix<double>& a,
                                         const Eigen::VectorXd& b, absl::string_view what,
                                         absl::string_view hint = "", int* iterations = nullptr);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_SPD_SOLVE_H_
