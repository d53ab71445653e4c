// The tangent operators D the Newton iterations can assemble K_t from.
#ifndef RVEHUB_FEM_CLIENT_CORE_TANGENT_OPERATOR_H_
#define RVEHUB_FEM_CLIENT_CORE_TANGENT_OPERATOR_H_

#include <Eigen/Dense>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "fem_client/core/material.h"

namespace rvehub::fem {

enum class TangentOperator {
  // The material's own tangent (the RVEs' contact tangent, G&Z eq. 9),
  // asked for on every iteration's Trial.
  kContact,
  // D^p by perturbation (G&Z eq. 8): 4 extra Trials per iteration.
  kPerturbation,
  // The contact tangent of the run's first Trial, kept for the whole run.
  kInitialElastic,
};

absl::string_view OperatorName(TangentOperator op);  // "contact", ...

// D^p of every point at ΔF from the responses `base` to ΔF: for each in-plane
// direction kl, one Trial of all points at ΔF + ξ e_k ⊗ e_l, and
//   D(:, 3k + l) = (σ(ΔF + ξ e_k ⊗ e_l) − σ(ΔF)) / ξ,   ξ [-].
// 01 and 10 are perturbed and kept apart (G&Z's four perturbations in 2D):
// D^p is then the derivative with respect to ΔF itself, the stress's
// response to spin included, which the solver contracts with the whole
// gradient of δu (averaging the two columns would keep only the response
// to shear strain). Out-of-plane columns are zero. A Trial's error is
// returned as it is.
absl::StatusOr<std::vector<Tangent>> PerturbationTangents(GaussPointMaterial& material,
                                                          std::span<const Eigen::Matrix3d> delta_f,
                                                          std::span<const PointResponse> base,
                                                          double xi);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_TANGENT_OPERATOR_H_
