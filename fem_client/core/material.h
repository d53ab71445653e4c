// The only way the solver sees stresses: the Gauss points' material (the
// RVEs behind them, or a stand-in). Plane strain: ΔF and σ are 3×3 with
// ΔF_zz = 1; Cauchy stress, tension positive, Pa.
#ifndef RVEHUB_FEM_CLIENT_CORE_MATERIAL_H_
#define RVEHUB_FEM_CLIENT_CORE_MATERIAL_H_

#include <Eigen/Dense>
#include <optional>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace rvehub::fem {

// D(3i + j, 3k + l) = D_ijkl = ∂σ_ij/∂ΔF_kl, Pa, where ΔF_kl = δ_kl +
// ∂Δu_k/∂X_l is the material's input (X: the configuration at the start of
// the step). A strain tangent with the minor symmetry D_ijkl = D_ijlk (G&Z
// eq. 9) gives dσ = D : dε with dε = sym(dΔF): the solver contracts D with
// the whole gradient, so such a D acts on its symmetric part only, while a
// D without it (the perturbation tangent, an exact derivative) carries the
// stress's response to spin too. Only the in-plane i, j, k, l ∈ {0, 1} are
// read.
using Tangent = Eigen::Matrix<double, 9, 9>;

inline int TangentIndex(int i, int j) { return 3 * i + j; }

struct PointResponse {
  Eigen::Matrix3d stress = Eigen::Matrix3d::Zero();  // Cauchy, tension positive, Pa
  std::optional<Tangent> tangent;                    // when asked for, Pa
};

class GaussPointMaterial {
 public:
  virtual ~GaussPointMaterial() = default;
  // Responses of every Gauss point (in order) to ΔF from its committed state;
  // changes nothing. A failure one point caused should say which
  // (PointFailure) so that the solver can name it.
  virtual absl::StatusOr<std::vector<PointResponse>> Trial(std::span<const Eigen::Matrix3d> delta_f,
                                                           bool want_tangent) = 0;
  // Makes delta_f each point's committed increment (the last Trial of the
  // same ΔF's result becomes the state).
  virtual absl::Status Commit(std::span<const Eigen::Matrix3d> delta_f) = 0;
};

// `status` marked as caused by Gauss point `point` (a payload; the message is
// kept). OK stays OK.
absl::Status PointFailure(absl::Status status, int point);
// The point a PointFailure marked, if any.
std::optional<int> FailedPoint(const absl::Status& status);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_MATERIAL_H_
