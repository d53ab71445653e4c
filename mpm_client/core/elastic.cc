#include "mpm_client/core/elastic.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace rvehub::mpm {

Eigen::Matrix3d ElasticStressUpdate(const Eigen::Matrix3d& stress, const Eigen::Matrix3d& delta_f,
                                    double lambda, double shear) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  r.topLeftCorner<2, 2>() = PolarRotation(delta_f.topLeftCorner<2, 2>());
  const Eigen::Matrix3d h = delta_f - Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d strain = 0.5 * (h + h.transpose());
  return r * stress * r.transpose() + lambda * strain.trace() * Eigen::Matrix3d::Identity() +
         2.0 * shear * strain;
}

LinearElasticModel::LinearElasticModel(double youngs, double poisson)
    : youngs_(youngs), poisson_(poisson) {}

absl::Status LinearElasticModel::Update(std::int64_t /*step*/,
                                        std::span<const Eigen::Matrix3d> delta_f,
                                        std::span<PointResponse> out) {
  if (!(youngs_ > 0.0) || !(poisson_ > -1.0 && poisson_ < 0.5)) {
    return absl::InvalidArgumentError(
        absl::StrCat("elastic model: E = ", youngs_, ", nu = ", poisson_, " are invalid"));
  }
  if (stress_.empty()) stress_.assign(delta_f.size(), Eigen::Matrix3d::Zero());
  if (stress_.size() != delta_f.size() || out.size() != delta_f.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("elastic model has ", stress_.size(), " points, update has ", delta_f.size()));
  }
  const double shear = ShearModulus(youngs_, poisson_);
  const double lambda = LameLambda(youngs_, poisson_);
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    stress_[p] = ElasticStressUpdate(stress_[p], delta_f[p], lambda, shear);
    out[p] = PointResponse();
    out[p].stress = stress_[p];
  }
  return absl::OkStatus();
}

}  // namespace rvehub::mpm
