#include "fem_client/run/rve_material.h"

#include <utility>

namespace rvehub::fem {

Tangent SymmetricTangent(const Eigen::Matrix<double, 9, 9>& contact) {
  Tangent d = Tangent::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      for (int k = 0; k < 3; ++k) {
        for (int l = 0; l < 3; ++l) {
          // Summed in pairs so that swapping i, j or k, l sums the same
          // numbers in the same order: the symmetries hold bit for bit.
          d(3 * i + j, 3 * k + l) =
              0.25 * ((contact(3 * i + j, 3 * k + l) + contact(3 * i + j, 3 * l + k)) +
                      (contact(3 * j + i, 3 * k + l) + contact(3 * j + i, 3 * l + k)));
        }
      }
    }
  }
  return d;
}

RveMaterial::RveMaterial(client::RvePool* pool, std::int64_t committed_step)
    : pool_(pool), committed_step_(committed_step) {}

absl::StatusOr<std::vector<PointResponse>> RveMaterial::Trial(
    std::span<const Eigen::Matrix3d> delta_f, bool want_tangent) {
  absl::StatusOr<std::vector<dem::RveState>> states =
      pool_->Trial(committed_step_ + 1, delta_f, want_tangent);
  if (!states.ok()) return states.status();
  std::vector<PointResponse> out(states->size());
  for (std::size_t k = 0; k < out.size(); ++k) {
    out[k].stress = (*states)[k].stress;
    if ((*states)[k].tangent.has_value()) out[k].tangent = SymmetricTangent(*(*states)[k].tangent);
  }
  last_trial_ = *std::move(states);
  return out;
}

absl::Status RveMaterial::Commit(std::span<const Eigen::Matrix3d> delta_f) {
  absl::StatusOr<std::vector<dem::RveState>> states = pool_->Apply(committed_step_ + 1, delta_f);
  if (!states.ok()) return states.status();
  committed_ = *std::move(states);
  ++committed_step_;
  return absl::OkStatus();
}

}  // namespace rvehub::fem
