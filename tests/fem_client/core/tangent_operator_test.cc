#include "fem_client/core/tangent_operator.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "absl/status/status.h"
#include "fem_client/core/elastic_material.h"
#include "tests/fem_client/core/fem_test_util.h"

namespace rvehub::fem {
namespace {

using testing::InPlane;
using testing::Prestress;
using testing::SpyMaterial;

double RelativeError(const std::vector<Tangent>& a, const std::vector<Tangent>& b) {
  double error = 0.0, scale = 0.0;
  for (std::size_t p = 0; p < a.size(); ++p) {
    error = std::max(error, (a[p] - b[p]).cwiseAbs().maxCoeff());
    scale = std::max(scale, b[p].cwiseAbs().maxCoeff());
  }
  return error / scale;
}

// D^p (G&Z eq. 8) is a forward difference: it differs from the exact
// tangent by O(ξ) — the error halves with ξ — and at G&Z's ξ = 5e-5 by
// about ξ·α (α = 40: 2e-3) of D. Each evaluation is 4 Trials.
TEST(TangentOperatorTest, PerturbationAgreesWithTheExactTangentToOrderXi) {
  auto material = StiffeningElasticMaterial::Create({5e7, 3e7, 40.0}, {Prestress(), Prestress()});
  ASSERT_TRUE(material.ok());
  Eigen::Matrix2d squeeze;
  squeeze << 0.995, 0.002, 0.0, 0.99;
  ASSERT_TRUE((*material)->Commit(std::vector<Eigen::Matrix3d>(2, InPlane(squeeze))).ok());
  Eigen::Matrix2d f0, f1;
  f0 << 0.985, 0.012, -0.02, 1.006;
  f1 << 1.004, -0.007, 0.003, 0.992;
  const std::vector<Eigen::Matrix3d> delta_f = {InPlane(f0), InPlane(f1)};
  const auto base = (*material)->Trial(delta_f, true);
  ASSERT_TRUE(base.ok()) << base.status();
  std::vector<Tangent> exact;
  for (const PointResponse& r : *base) exact.push_back(*r.tangent);
  SpyMaterial spy(material->get());
  std::vector<double> errors;
  for (double xi : {4e-4, 2e-4, 1e-4, 5e-5}) {
    const auto dp = PerturbationTangents(spy, delta_f, *base, xi);
    ASSERT_TRUE(dp.ok()) << dp.status();
    errors.push_back(RelativeError(*dp, exact));
  }
  EXPECT_EQ(spy.trials, 4 * 4);
  EXPECT_EQ(spy.tangent_trials, 0);
  for (std::size_t k = 1; k < errors.size(); ++k) {
    EXPECT_NEAR(errors[k - 1] / errors[k], 2.0, 0.1) << k;
  }
  EXPECT_LT(errors.back(), 40.0 * 5e-5);
}

// With prestress, columns 01 and 10 differ by the stress's response to
// spin: for the linear stand-in at ΔF = I, Ωσ − σΩ with Ω = e_0 ⊗ e_1 −
// e_1 ⊗ e_0 (both perturbations strain the same, and turn by ±ξ/2). ξ is
// small here so that the strain's second-order part, ~ξ·C, stays well
// below the spin's σ.
TEST(TangentOperatorTest, PerturbationKeeps01And10ApartForTheirSpin) {
  auto material = LinearElasticMaterial::Create(1e8, 0.3, {Prestress()});
  ASSERT_TRUE(material.ok());
  const std::vector<Eigen::Matrix3d> identity = {Eigen::Matrix3d::Identity()};
  const auto base = (*material)->Trial(identity, false);
  ASSERT_TRUE(base.ok());
  const auto dp = PerturbationTangents(**material, identity, *base, 1e-7);
  ASSERT_TRUE(dp.ok()) << dp.status();
  Eigen::Matrix3d omega = Eigen::Matrix3d::Zero();
  omega(0, 1) = 1.0;
  omega(1, 0) = -1.0;
  const Eigen::Matrix3d spin = omega * Prestress() - Prestress() * omega;
  const Eigen::Matrix<double, 9, 1> difference =
      (*dp)[0].col(TangentIndex(0, 1)) - (*dp)[0].col(TangentIndex(1, 0));
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      EXPECT_NEAR(difference[TangentIndex(i, j)], spin(i, j), 1e-3 * Prestress().norm()) << i << j;
    }
  }
  // The out-of-plane columns are never perturbed.
  EXPECT_EQ((*dp)[0].col(TangentIndex(2, 2)).norm(), 0.0);
}

TEST(TangentOperatorTest, ATrialFailureInAPerturbationIsReturnedAsItIs) {
  auto material = LinearElasticMaterial::Create(1e8, 0.3, {Prestress()});
  ASSERT_TRUE(material.ok());
  SpyMaterial spy(material->get());
  spy.fail = [](std::span<const Eigen::Matrix3d>) {
    return PointFailure(absl::UnavailableError("the RVE's server went away"), 0);
  };
  const std::vector<Eigen::Matrix3d> identity = {Eigen::Matrix3d::Identity()};
  const std::vector<PointResponse> base = {PointResponse{Prestress(), {}}};
  const absl::Status s = PerturbationTangents(spy, identity, base, 5e-5).status();
  EXPECT_EQ(s.code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(FailedPoint(s), 0);
}

}  // namespace
}  // namespace rvehub::fem
