#include "mpm_client/core/spd_solve.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <span>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace rvehub::mpm {

absl::StatusOr<Eigen::VectorXd> SolveSpd(const Eigen::SparseMatrix<double>& a,
                                         const Eigen::VectorXd& b, absl::string_view what,
                                         absl::string_view hint, int* iterations) {
  const auto unstable = [&](absl::string_view why) {
    return absl::InternalError(
        absl::StrCat(what, " met ", why, ": the solution became unstable (time step too large?)"));
  };
  const auto matrix_values = [&] { return std::span(a.valuePtr(), a.nonZeros()); };
  if (!b.allFinite() ||
      !std::ranges::all_of(matrix_values(), [](double x) { return std::isfinite(x); })) {
    return unstable("a value that is not finite in its matrix or right-hand side");
  }
  // CG works with squared norms: past about 1e154 they overflow and every
  // iterate turns NaN, which is the step's size, not the system's fault.
  const double matrix_norm2 =
      std::transform_reduce(matrix_values().begin(), matrix_values().end(), 0.0, std::plus<>(),
                            [](double x) { return x * x; });
  if (!std::isfinite(b.squaredNorm()) || !std::isfinite(matrix_norm2)) {
    return unstable("values too large to solve (its squared norms overflow)");
  }
  Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
  cg.setTolerance(kSpdTolerance);
  cg.setMaxIterations(std::max<Eigen::Index>(1000, 4 * a.rows()));
  cg.compute(a);
  Eigen::VectorXd x = cg.solve(b);
  if (iterations != nullptr) *iterations = static_cast<int>(cg.iterations());
  const auto with_hint = [&](absl::string_view message) {
    return absl::InternalError(absl::StrCat(what, " ", message, hint.empty() ? "" : ": ", hint));
  };
  // From moderate, finite input CG only breaks down (a zero or negative
  // curvature p·Ap, then NaN) on a matrix that is singular or not positive
  // definite: for the pore pressure, soil that no drained boundary reaches.
  if (!x.allFinite() || !std::isfinite(cg.error())) {
    return with_hint(
        "broke down (its iterates are not finite: the matrix is singular or not positive "
        "definite)");
  }
  const bool stalled = cg.info() == Eigen::NoConvergence && cg.error() <= kSpdStalledTolerance;
  if (cg.info() != Eigen::Success && !stalled) {
    return with_hint(absl::StrCat("did not converge (", cg.iterations(), " iterations, error ",
                                  cg.error(), ")"));
  }
  return x;
}

}  // namespace rvehub::mpm
