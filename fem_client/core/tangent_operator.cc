#include "fem_client/core/tangent_operator.h"

#include "absl/strings/str_cat.h"

namespace rvehub::fem {

absl::string_view OperatorName(TangentOperator op) {
  switch (op) {
    case TangentOperator::kContact:
      return "contact";
    case TangentOperator::kPerturbation:
      return "perturbation";
    case TangentOperator::kInitialElastic:
      return "initial elastic";
  }
  return "unknown";
}

absl::StatusOr<std::vector<Tangent>> PerturbationTangents(GaussPointMaterial& material,
                                                          std::span<const Eigen::Matrix3d> delta_f,
                                                          std::span<const PointResponse> base,
                                                          double xi) {
  if (base.size() != delta_f.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("perturbation: ", delta_f.size(), " points but ", base.size(), " responses"));
  }
  std::vector<Tangent> d(delta_f.size(), Tangent::Zero());
  std::vector<Eigen::Matrix3d> perturbed(delta_f.begin(), delta_f.end());
  for (int k = 0; k < 2; ++k) {
    for (int l = 0; l < 2; ++l) {
      for (std::size_t p = 0; p < perturbed.size(); ++p) {
        perturbed[p] = delta_f[p];
        perturbed[p](k, l) += xi;
      }
      absl::StatusOr<std::vector<PointResponse>> r = material.Trial(perturbed, false);
      if (!r.ok()) return r.status();
      if (r->size() != delta_f.size()) {
        return absl::InternalError(absl::StrCat("perturbation: the material returned ", r->size(),
                                                " responses for ", delta_f.size(), " points"));
      }
      for (std::size_t p = 0; p < perturbed.size(); ++p) {
        const Eigen::Matrix3d ds = ((*r)[p].stress - base[p].stress) / xi;
        for (int i = 0; i < 3; ++i) {
          for (int j = 0; j < 3; ++j) d[p](TangentIndex(i, j), TangentIndex(k, l)) = ds(i, j);
        }
      }
    }
  }
  return d;
}

}  // namespace rvehub::fem
