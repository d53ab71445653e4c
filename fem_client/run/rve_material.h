// The Gauss points' material backed by RVEs (G&Z §2.3 steps 2a–2d): Gauss
// point k is RVE k of the pool's run. Each Trial is one batched TRIAL per
// RVE server of the step after the committed one, each point's ΔF taken from
// its committed state; Commit is one batched COMMIT of the converged ΔF,
// after which the RVEs hold what the last Trial of that ΔF returned, bit for
// bit (the registry computes a COMMIT as the TRIAL of the same ΔF).
#ifndef RVEHUB_FEM_CLIENT_RUN_RVE_MATERIAL_H_
#define RVEHUB_FEM_CLIENT_RUN_RVE_MATERIAL_H_

#include <Eigen/Dense>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "fem_client/core/material.h"
#include "rve_server/client/rve_pool.h"
#include "rve_server/values/state.h"

namespace rvehub::fem {

// The contact tangent of an RVE (G&Z eq. 9, D_ijkl with dσ_ij = D_ijkl dε_kl,
// Pa, as the server returns it) as a strain tangent with both minor
// symmetries: ¼(D_ijkl + D_jikl + D_ijlk + D_jilk). The packing's sum over
// contacts has them only where every branch vector lies along its normal; σ
// and ε are symmetric, so only this part acts, and the solver reads a
// minor-symmetric D as D : sym(dΔF).
Tangent SymmetricTangent(const Eigen::Matrix<double, 9, 9>& contact);

class RveMaterial : public GaussPointMaterial {
 public:
  // `pool`'s RVEs exist (ids 0..n−1, one per Gauss point) at committed step
  // `committed_step`; `pool` outlives this material.
  RveMaterial(client::RvePool* pool, std::int64_t committed_step);

  absl::StatusOr<std::vector<PointResponse>> Trial(std::span<const Eigen::Matrix3d> delta_f,
                                                   bool want_tangent) override;
  absl::Status Commit(std::span<const Eigen::Matrix3d> delta_f) override;

  std::int64_t committed_step() const { return committed_step_; }
  // Takes up a run from its checkpoint: the RVEs' committed step and the
  // states the outputs read of them.
  void Restore(std::int64_t committed_step, std::vector<dem::RveState> committed) {
    committed_step_ = committed_step;
    committed_ = std::move(committed);
  }
  // The RVEs' states after the last Commit (empty before the first), Gauss
  // point order: void ratio, fabric, coordination for the outputs.
  const std::vector<dem::RveState>& committed() const { return committed_; }
  // The states of the last successful Trial.
  const std::vector<dem::RveState>& last_trial() const { return last_trial_; }

 private:
  client::RvePool* pool_;
  std::int64_t committed_step_;
  std::vector<dem::RveState> committed_, last_trial_;
};

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_RUN_RVE_MATERIAL_H_
