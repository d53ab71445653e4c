#include "fem_client/core/elastic_material.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"

namespace rvehub::fem {
namespace {

constexpr double kE = 1e8, kNu = 0.3;  // Pa, [-]

Eigen::Matrix3d InPlane(const Eigen::Matrix2d& a) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  m.topLeftCorner<2, 2>() = a;
  return m;
}

Eigen::Matrix3d Rotation(double theta) {
  Eigen::Matrix2d r;
  r << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
  return InPlane(r);
}

Eigen::Matrix3d Prestress() {
  Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
  s(0, 0) = -2e5;
  s(1, 1) = -1e5;
  s(0, 1) = s(1, 0) = 3e4;
  s(2, 2) = -1.5e5;
  return s;
}

// An increment with stretch, shear and rotation.
Eigen::Matrix3d GeneralIncrement() {
  Eigen::Matrix2d f;
  f << 0.985, 0.012, -0.02, 1.006;
  return InPlane(f);
}

// Under ΔF = diag(1 + ε, 1) (V = ΔF, no rotation): σ_xx = (λ + 2G) ε,
// σ_yy = σ_zz = λ ε, exactly.
TEST(ElasticMaterialTest, LinearUniaxialStrainHasTheClosedForm) {
  auto m = LinearElasticMaterial::Create(kE, kNu, {Eigen::Matrix3d::Zero()});
  ASSERT_TRUE(m.ok()) << m.status();
  const double eps = -1e-3, lambda = LameLambda(kE, kNu), shear = ShearModulus(kE, kNu);
  const Eigen::Matrix3d f = InPlane(Eigen::Vector2d(1.0 + eps, 1.0).asDiagonal());
  const auto r = (*m)->Trial(std::vector<Eigen::Matrix3d>{f}, true);
  ASSERT_TRUE(r.ok()) << r.status();
  const Eigen::Matrix3d& s = (*r)[0].stress;
  EXPECT_NEAR(s(0, 0), (lambda + 2 * shear) * eps, 1e-9 * kE * std::abs(eps));
  EXPECT_NEAR(s(1, 1), lambda * eps, 1e-9 * kE * std::abs(eps));
  EXPECT_NEAR(s(2, 2), lambda * eps, 1e-9 * kE * std::abs(eps));
  EXPECT_EQ(*(*r)[0].tangent, IsotropicTangent(lambda, shear));
  EXPECT_EQ((*m)->stress()[0], Eigen::Matrix3d::Zero());  // a Trial changes nothing
  ASSERT_TRUE((*m)->Commit(std::vector<Eigen::Matrix3d>{f}).ok());
  EXPECT_EQ((*m)->stress()[0], s);
}

// A rigid rotation of any angle strains nothing: both stand-ins return the
// committed stress rotated, R σ Rᵀ.
TEST(ElasticMaterialTest, RigidRotationsRotateTheStressObjectively) {
  const Eigen::Matrix3d r = Rotation(0.9);
  const Eigen::Matrix3d expected = r * Prestress() * r.transpose();
  auto linear = LinearElasticMaterial::Create(kE, kNu, {Prestress()});
  auto stiffening = StiffeningElasticMaterial::Create({5e7, 3e7, 40.0}, {Prestress()});
  ASSERT_TRUE(linear.ok() && stiffening.ok());
  for (GaussPointMaterial* m : {static_cast<GaussPointMaterial*>(linear->get()),
                                static_cast<GaussPointMaterial*>(stiffening->get())}) {
    const auto out = m->Trial(std::vector<Eigen::Matrix3d>{r}, false);
    ASSERT_TRUE(out.ok()) << out.status();
    EXPECT_LT(((*out)[0].stress - expected).norm(), 1e-9 * Prestress().norm());
    EXPECT_FALSE((*out)[0].tangent.has_value());
  }
  EXPECT_NEAR(PolarRotation(r.topLeftCorner<2, 2>() * Eigen::Vector2d(1.1, 0.9).asDiagonal())(1, 0),
              std::sin(0.9), 1e-15);
}

// The linear stand-in's C is its derivative at ΔF = I without prestress,
// for stretch and shear; a spin changes nothing there.
TEST(ElasticMaterialTest, LinearTangentIsTheDerivativeAtTheStart) {
  auto m = LinearElasticMaterial::Create(kE, kNu, {Eigen::Matrix3d::Zero()});
  ASSERT_TRUE(m.ok());
  const Tangent c = IsotropicTangent(LameLambda(kE, kNu), ShearModulus(kE, kNu));
  const double h = 1e-7;
  for (int k = 0; k < 2; ++k) {
    for (int l = 0; l < 2; ++l) {
      Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
      a(k, l) += 0.5;  // a symmetric direction: pure strain
      a(l, k) += 0.5;
      const auto plus =
          (*m)->Trial(std::vector<Eigen::Matrix3d>{Eigen::Matrix3d::Identity() + h * a}, false);
      const auto minus =
          (*m)->Trial(std::vector<Eigen::Matrix3d>{Eigen::Matrix3d::Identity() - h * a}, false);
      const Eigen::Matrix3d ds = ((*plus)[0].stress - (*minus)[0].stress) / (2 * h);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          const double expected = c(TangentIndex(i, j), TangentIndex(k, l));
          EXPECT_NEAR(ds(i, j), expected, 1e-6 * kE) << i << j << k << l;
        }
      }
    }
  }
}

// The stiffening stand-in's tangent is ∂σ/∂ΔF exactly, with prestress,
// rotation and a committed volumetric strain: central differences agree to
// their own error, O(h² ∂³σ) ~ 1e-7 of D here.
TEST(ElasticMaterialTest, StiffeningTangentIsTheExactDerivative) {
  const StiffeningParameters p{5e7, 3e7, 40.0};
  const StiffeningState committed{Prestress(), -0.01};
  Tangent d;
  const Eigen::Matrix3d f = GeneralIncrement();
  StiffeningStress(p, committed, f, &d);
  const double h = 1e-6;
  double largest = 0.0;
  for (int k = 0; k < 2; ++k) {
    for (int l = 0; l < 2; ++l) {
      Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
      a(k, l) = h;
      const Eigen::Matrix3d ds =
          (StiffeningStress(p, committed, f + a) - StiffeningStress(p, committed, f - a)) / (2 * h);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          largest =
              std::max(largest, std::abs(ds(i, j) - d(TangentIndex(i, j), TangentIndex(k, l))));
        }
      }
    }
  }
  EXPECT_LT(largest, 1e-6 * d.cwiseAbs().maxCoeff());
  // No minor symmetry: the 01 and 10 columns differ by the response to spin.
  EXPECT_GT((d.col(TangentIndex(0, 1)) - d.col(TangentIndex(1, 0))).norm(), 1e-3 * d.norm());
}

// At ΔF = I with no prestress the tangent is K(e) I⊗I + 2G (I − I⊗I/3),
// K(e) = K0 exp(−α e): stiffer after a committed compression.
TEST(ElasticMaterialTest, StiffeningBulkModulusGrowsUnderCompression) {
  const StiffeningParameters p{5e7, 3e7, 40.0};
  auto m = StiffeningElasticMaterial::Create(p, {Eigen::Matrix3d::Zero()});
  ASSERT_TRUE(m.ok());
  const Eigen::Matrix3d squeeze = InPlane(0.99 * Eigen::Matrix2d::Identity());
  ASSERT_TRUE((*m)->Commit(std::vector<Eigen::Matrix3d>{squeeze}).ok());
  const double e = (*m)->state()[0].volumetric;
  EXPECT_NEAR(e, 0.99 * 0.99 - 1.0, 1e-15);  // tr E = 2·½(0.99² − 1)
  Tangent d;
  StiffeningStress(p, {Eigen::Matrix3d::Zero(), e}, Eigen::Matrix3d::Identity(), &d);
  const double bulk = p.bulk * std::exp(-p.alpha * e);
  EXPECT_NEAR(d(0, 0), bulk + 4.0 / 3.0 * p.shear, 1e-9 * bulk);
  EXPECT_NEAR(d(0, TangentIndex(1, 1)), bulk - 2.0 / 3.0 * p.shear, 1e-9 * bulk);
  EXPECT_GT(bulk, 2.0 * p.bulk);
}

TEST(ElasticMaterialTest, BadParametersAndIncrementsAreErrors) {
  EXPECT_EQ(LinearElasticMaterial::Create(-1.0, 0.3, {}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(LinearElasticMaterial::Create(kE, 0.5, {}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(StiffeningElasticMaterial::Create({1.0, 1.0, -1.0}, {}).status().code(),
            absl::StatusCode::kInvalidArgument);
  auto m = LinearElasticMaterial::Create(kE, kNu,
                                         std::vector<Eigen::Matrix3d>(3, Eigen::Matrix3d::Zero()));
  ASSERT_TRUE(m.ok());
  EXPECT_EQ((*m)->Trial(std::vector<Eigen::Matrix3d>(2, Eigen::Matrix3d::Identity()), false)
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  std::vector<Eigen::Matrix3d> f(3, Eigen::Matrix3d::Identity());
  f[1](0, 0) = -0.5;  // inverted
  const absl::Status s = (*m)->Trial(f, false).status();
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(FailedPoint(s), 1);
  // Extreme compression overflows K: a failure of that point, not a NaN.
  auto stiff = StiffeningElasticMaterial::Create(
      {5e7, 3e7, 2000.0}, std::vector<Eigen::Matrix3d>(2, Eigen::Matrix3d::Zero()));
  ASSERT_TRUE(stiff.ok());
  std::vector<Eigen::Matrix3d> g(2, Eigen::Matrix3d::Identity());
  g[1] = InPlane(0.5 * Eigen::Matrix2d::Identity());
  const absl::Status overflow = (*stiff)->Trial(g, true).status();
  EXPECT_EQ(overflow.code(), absl::StatusCode::kOutOfRange) << overflow;
  EXPECT_EQ(FailedPoint(overflow), 1);
  EXPECT_EQ(FailedPoint(absl::InternalError("no point")), std::nullopt);
}

}  // namespace
}  // namespace rvehub::fem
