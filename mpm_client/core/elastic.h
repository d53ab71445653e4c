// A hypoelastic plane-strain material for tests and checks of the solver
// (wave speeds, reactions): no RVEs behind it.
#ifndef RVEHUB_MPM_CLIENT_CORE_ELASTIC_H_
#define RVEHUB_MPM_CLIENT_CORE_ELASTIC_H_

#include <Eigen/Dense>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "mpm_client/core/solver.h"
#include "rve_server/common/elasticity.h"

namespace rvehub::mpm {

// PolarRotation, PWaveModulus, LameLambda, ShearModulus.
using ::rvehub::LameLambda;
using ::rvehub::PolarRotation;
using ::rvehub::PWaveModulus;
using ::rvehub::ShearModulus;

// σ ← R σ Rᵀ + λ tr(Δε) I + 2G Δε with Δε = sym(ΔF − I) and R the rotation
// of ΔF (3×3 plane strain, ΔF_zz = 1): Pa, tension +.
Eigen::Matrix3d ElasticStressUpdate(const Eigen::Matrix3d& stress, const Eigen::Matrix3d& delta_f,
                                    double lambda, double shear);

class LinearElasticModel : public StressModel {
 public:
  LinearElasticModel(double youngs, double poisson);  // Pa, [-]

  // The stress of every point (Pa, tension +); zero if never set.
  void SetStress(std::vector<Eigen::Matrix3d> stress) { stress_ = std::move(stress); }
  const std::vector<Eigen::Matrix3d>& stress() const { return stress_; }

  // InvalidArgument for E ≤ 0, ν outside (−1, 0.5), or a point count that
  // differs from the stresses set.
  absl::Status Update(std::int64_t step, std::span<const Eigen::Matrix3d> delta_f,
                      std::span<PointResponse> out) override;

 private:
  double youngs_, poisson_;
  std::vector<Eigen::Matrix3d> stress_;
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_ELASTIC_H_
