#include "fem_client/core/element.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"

namespace rvehub::fem {
namespace {

constexpr ElementType kTypes[] = {ElementType::kQ4, ElementType::kQ8};

// A distorted quadrilateral (counter-clockwise corners), Q8's midsides at
// its edges' midpoints, and for Q8 one midside moved off its edge (a curved
// side) to show the isoparametric map handles it.
ElementCoordinates Distorted(ElementType type, bool curved = false) {
  const Eigen::Vector2d corner[4] = {{0.1, -0.2}, {2.3, 0.1}, {1.9, 1.7}, {-0.2, 1.2}};
  ElementCoordinates x(NodeCount(type), 2);
  for (int a = 0; a < 4; ++a) x.row(a) = corner[a].transpose();
  if (type == ElementType::kQ8) {
    for (int a = 0; a < 4; ++a) x.row(4 + a) = 0.5 * (x.row(a) + x.row((a + 1) % 4));
    if (curved) x.row(5) += Eigen::RowVector2d(0.15, 0.05);
  }
  return x;
}

// Points inside the element and on its border, where the identities hold.
std::vector<Eigen::Vector2d> SamplePoints() {
  return {{0.0, 0.0}, {0.3, -0.7}, {-1.0, 0.4}, {1.0, 1.0}, {-0.9, 0.95}, {0.577, -0.11}};
}

// Σ N_a = 1 and Σ N_a ξ_a = ξ (so a linear field is reproduced), with their
// derivatives: exact identities of both families, to round-off.
TEST(ElementTest, ShapeFunctionsArePartitionsOfUnityAndReproduceLinearFields) {
  for (ElementType type : kTypes) {
    const ElementCoordinates natural = [&] {
      ElementCoordinates c(NodeCount(type), 2);
      const double xi[8][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1},
                               {0, -1},  {1, 0},  {0, 1}, {-1, 0}};
      for (int a = 0; a < c.rows(); ++a) c.row(a) << xi[a][0], xi[a][1];
      return c;
    }();
    for (const Eigen::Vector2d& xi : SamplePoints()) {
      const ShapeVector n = ShapeFunctions(type, xi);
      const ShapeGradient d = ShapeDerivatives(type, xi);
      EXPECT_NEAR(n.sum(), 1.0, 1e-15) << ElementName(type);
      EXPECT_LT(d.colwise().sum().norm(), 1e-15) << ElementName(type);
      EXPECT_LT((natural.transpose() * n - xi).norm(), 1e-15) << ElementName(type);
      EXPECT_LT((natural.transpose() * d - Eigen::Matrix2d::Identity()).norm(), 1e-15);
    }
  }
}

TEST(ElementTest, EachShapeFunctionIsOneAtItsNodeAndZeroAtTheOthers) {
  const double xi[8][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}, {0, -1}, {1, 0}, {0, 1}, {-1, 0}};
  for (ElementType type : kTypes) {
    for (int b = 0; b < NodeCount(type); ++b) {
      const ShapeVector n = ShapeFunctions(type, Eigen::Vector2d(xi[b][0], xi[b][1]));
      for (int a = 0; a < NodeCount(type); ++a) EXPECT_EQ(n[a], a == b ? 1.0 : 0.0);
    }
  }
}

// Central differences of step h have an error of order h² ∂³N ~ 1e-12 and
// round-off 1e-16/h ~ 1e-10: 1e-9 separates a wrong derivative from those.
TEST(ElementTest, DerivativesMatchFiniteDifferences) {
  const double h = 1e-6;
  for (ElementType type : kTypes) {
    for (const Eigen::Vector2d& xi : SamplePoints()) {
      const ShapeGradient d = ShapeDerivatives(type, xi);
      for (int j = 0; j < 2; ++j) {
        const Eigen::Vector2d step = h * Eigen::Vector2d::Unit(j);
        const ShapeVector fd =
            (ShapeFunctions(type, xi + step) - ShapeFunctions(type, xi - step)) / (2.0 * h);
        EXPECT_LT((fd - d.col(j)).cwiseAbs().maxCoeff(), 1e-9) << ElementName(type) << " j " << j;
      }
    }
  }
}

// Gauss–Legendre with n points per axis is exact for degree 2n − 1 per
// axis: ∫ ξ^a η^b over [−1, 1]² to round-off up to 3 (Q4) and 5 (Q8), and
// wrong one degree above (the rule is the one claimed, not a finer one).
TEST(ElementTest, GaussRulesIntegratePolynomialsExactlyToTheirDegree) {
  const auto exact = [](int a) { return a % 2 == 1 ? 0.0 : 2.0 / (a + 1); };
  for (ElementType type : kTypes) {
    const int degree = type == ElementType::kQ4 ? 3 : 5;
    for (int a = 0; a <= degree + 1; ++a) {
      for (int b = 0; b <= degree + 1; ++b) {
        double sum = 0.0;
        for (const GaussPoint& gp : GaussPoints(type)) {
          sum += gp.weight * std::pow(gp.xi.x(), a) * std::pow(gp.xi.y(), b);
        }
        if (a <= degree && b <= degree) {
          EXPECT_NEAR(sum, exact(a) * exact(b), 1e-14) << ElementName(type) << " " << a << " " << b;
        } else if ((a == degree + 1 && b == 0) || (a == 0 && b == degree + 1)) {
          EXPECT_GT(std::abs(sum - exact(a) * exact(b)), 0.01) << ElementName(type);
        }
      }
    }
  }
  double sum = 0.0;
  for (const Eigen::Vector2d& g : EdgeGaussPoints()) sum += g[1] * std::pow(g[0], 4);
  EXPECT_NEAR(sum, 0.4, 1e-15);
}

// Σ w det J is the area: the shoelace formula's for straight sides.
TEST(ElementTest, WeightsTimesDetJSumToTheArea) {
  for (ElementType type : kTypes) {
    const ElementCoordinates x = Distorted(type);
    double area = 0.0;
    for (int a = 0; a < 4; ++a) {
      area += 0.5 * (x(a, 0) * x((a + 1) % 4, 1) - x((a + 1) % 4, 0) * x(a, 1));
    }
    double sum = 0.0;
    for (int p = 0; p < GaussPointCount(type); ++p) {
      const absl::StatusOr<PointGeometry> g = EvaluatePoint(type, x, p, 0);
      ASSERT_TRUE(g.ok()) << g.status();
      sum += g->volume;
    }
    EXPECT_NEAR(sum, area, 1e-13 * area) << ElementName(type);
  }
}

// ∇_x of a linear field u = c + H x interpolated from the nodes is H at
// every Gauss point, however distorted (a curved Q8 side included).
TEST(ElementTest, GradientsOfALinearFieldAreExact) {
  Eigen::Matrix2d h;
  h << 0.3, -1.2, 0.7, 2.1;
  const Eigen::Vector2d c(0.5, -0.25);
  for (ElementType type : kTypes) {
    const ElementCoordinates x = Distorted(type, /*curved=*/true);
    ElementCoordinates u(x.rows(), 2);
    for (int a = 0; a < x.rows(); ++a) u.row(a) = (c + h * x.row(a).transpose()).transpose();
    for (int p = 0; p < GaussPointCount(type); ++p) {
      const absl::StatusOr<PointGeometry> g = EvaluatePoint(type, x, p, 0);
      ASSERT_TRUE(g.ok()) << g.status();
      EXPECT_LT((u.transpose() * g->gradient - h).norm(), 1e-13) << ElementName(type) << " " << p;
    }
  }
}

TEST(ElementTest, TheJacobianOfAnAffineMapIsItsMatrix) {
  Eigen::Matrix2d a;
  a << 2.0, 0.5, -0.25, 1.5;
  for (ElementType type : kTypes) {
    ElementCoordinates x(NodeCount(type), 2);
    const double xi[8][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}, {0, -1}, {1, 0}, {0, 1}, {-1, 0}};
    for (int k = 0; k < x.rows(); ++k) {
      x.row(k) = (a * Eigen::Vector2d(xi[k][0], xi[k][1]) + Eigen::Vector2d(3, 4)).transpose();
    }
    EXPECT_LT((Jacobian(ShapeDerivatives(type, {0.2, -0.6}), x) - a).norm(), 1e-15);
  }
}

TEST(ElementTest, AnInvertedElementIsNamedWithItsGaussPoint) {
  for (ElementType type : kTypes) {
    ElementCoordinates x = Distorted(type);
    x.col(0) *= -1.0;  // mirrored: clockwise
    const absl::StatusOr<PointGeometry> g = EvaluatePoint(type, x, 2, 7);
    ASSERT_EQ(g.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_TRUE(absl::StrContains(
        g.status().message(),
        "element 7 (" + std::string(ElementName(type)) + ") is inverted at Gauss point 2"))
        << g.status();
  }
}

TEST(ElementTest, ADegenerateElementIsNamedWithItsGaussPoint) {
  for (ElementType type : kTypes) {
    ElementCoordinates x = Distorted(type);
    x.col(1).setZero();  // every node on a line
    const absl::StatusOr<PointGeometry> g = EvaluatePoint(type, x, 0, 3);
    ASSERT_EQ(g.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_TRUE(absl::StrContains(g.status().message(), "is degenerate at Gauss point 0"))
        << g.status();
    EXPECT_TRUE(absl::StrContains(g.status().message(), "element 3")) << g.status();
  }
}

TEST(ElementTest, EdgeShapeFunctionsArePartitionsOfUnity) {
  for (int nodes : {2, 3}) {
    for (double s : {-1.0, -0.3, 0.0, 0.8, 1.0}) {
      EXPECT_NEAR(EdgeShapeFunctions(nodes, s).sum(), 1.0, 1e-15);
      EXPECT_NEAR(EdgeShapeDerivatives(nodes, s).sum(), 0.0, 1e-15);
      // s = Σ N_a s_a with s_a = −1, 1, 0.
      EXPECT_NEAR(EdgeShapeFunctions(nodes, s).dot(Eigen::Vector3d(-1, 1, 0)), s, 1e-15);
    }
  }
  // Faces run counter-clockwise with the midside last.
  EXPECT_EQ(FaceNodes(ElementType::kQ8, 3), (std::array<int, 3>{3, 0, 7}));
  EXPECT_EQ(FaceNodes(ElementType::kQ4, 1), (std::array<int, 3>{1, 2, -1}));
}

}  // namespace
}  // namespace rvehub::fem
