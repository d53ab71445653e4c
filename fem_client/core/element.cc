#include "fem_client/core/element.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace rvehub::fem {
namespace {

// Natural coordinates of the nodes, corners then midsides.
constexpr double kNodeXi[8][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1},
                                  {0, -1},  {1, 0},  {0, 1}, {-1, 0}};

std::array<GaussPoint, 4> MakeQ4Points() {
  const double a = 1.0 / std::sqrt(3.0);
  std::array<GaussPoint, 4> p;
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) p[2 * j + i] = {Eigen::Vector2d(i ? a : -a, j ? a : -a), 1.0};
  }
  return p;
}

std::array<GaussPoint, 9> MakeQ8Points() {
  const double a = std::sqrt(0.6);
  const double s[3] = {-a, 0.0, a};
  const double w[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
  std::array<GaussPoint, 9> p;
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 3; ++i) p[3 * j + i] = {Eigen::Vector2d(s[i], s[j]), w[i] * w[j]};
  }
  return p;
}

}  // namespace

int NodeCount(ElementType type) { return type == ElementType::kQ4 ? 4 : 8; }
int GaussPointCount(ElementType type) { return type == ElementType::kQ8 ? 9 : 4; }
int EdgeNodeCount(ElementType type) { return type == ElementType::kQ4 ? 2 : 3; }
absl::string_view ElementName(ElementType type) {
  switch (type) {
    case ElementType::kQ4:
      return "Q4";
    case ElementType::kQ8:
      return "Q8";
    case ElementType::kQ8R:
      break;
  }
  return "Q8R";
}

std::span<const GaussPoint> GaussPoints(ElementType type) {
  static const std::array<GaussPoint, 4> q4 = MakeQ4Points();
  static const std::array<GaussPoint, 9> q8 = MakeQ8Points();
  if (type == ElementType::kQ8) return q8;
  return q4;
}

ShapeVector ShapeFunctions(ElementType type, const Eigen::Vector2d& xi) {
  const int n = NodeCount(type);
  ShapeVector v(n);
  for (int a = 0; a < n; ++a) {
    const double xa = kNodeXi[a][0], ya = kNodeXi[a][1];
    const double s = 1.0 + xi.x() * xa, t = 1.0 + xi.y() * ya;
    if (type == ElementType::kQ4) {
      v[a] = 0.25 * s * t;
    } else if (a < 4) {
      v[a] = 0.25 * s * t * (xi.x() * xa + xi.y() * ya - 1.0);
    } else if (xa == 0.0) {
      v[a] = 0.5 * (1.0 - xi.x() * xi.x()) * t;
    } else {
      v[a] = 0.5 * s * (1.0 - xi.y() * xi.y());
    }
  }
  return v;
}

ShapeGradient ShapeDerivatives(ElementType type, const Eigen::Vector2d& xi) {
  const int n = NodeCount(type);
  const double x = xi.x(), y = xi.y();
  ShapeGradient d(n, 2);
  for (int a = 0; a < n; ++a) {
    const double xa = kNodeXi[a][0], ya = kNodeXi[a][1];
    if (type == ElementType::kQ4) {
      d(a, 0) = 0.25 * xa * (1.0 + y * ya);
      d(a, 1) = 0.25 * ya * (1.0 + x * xa);
    } else if (a < 4) {
      d(a, 0) = 0.25 * xa * (1.0 + y * ya) * (2.0 * x * xa + y * ya);
      d(a, 1) = 0.25 * ya * (1.0 + x * xa) * (x * xa + 2.0 * y * ya);
    } else if (xa == 0.0) {
      d(a, 0) = -x * (1.0 + y * ya);
      d(a, 1) = 0.5 * ya * (1.0 - x * x);
    } else {
      d(a, 0) = 0.5 * xa * (1.0 - y * y);
      d(a, 1) = -y * (1.0 + x * xa);
    }
  }
  return d;
}

Eigen::Matrix2d Jacobian(const ShapeGradient& dn_dxi, const ElementCoordinates& x) {
  return x.transpose() * dn_dxi;
}

absl::StatusOr<PointGeometry> EvaluatePoint(ElementType type, const ElementCoordinates& x,
                                            int point, int element) {
  const GaussPoint& gp = GaussPoints(type)[point];
  const ShapeGradient dn = ShapeDerivatives(type, gp.xi);
  const Eigen::Matrix2d j = Jacobian(dn, x);
  const double det = j.determinant();
  // Relative to ‖J‖² so that the test does not depend on the units of x.
  if (!(std::abs(det) > 1e-12 * j.squaredNorm())) {
    return absl::InvalidArgumentError(absl::StrCat(
        "element ", element, " (", ElementName(type), ") is degenerate at Gauss point ", point,
        ": det J = ", det, " (its nodes are collinear or coincide)"));
  }
  if (det < 0.0) {
    return absl::InvalidArgumentError(absl::StrCat("element ", element, " (", ElementName(type),
                                                   ") is inverted at Gauss point ", point,
                                                   ": det J = ", det, " < 0"));
  }
  PointGeometry g;
  // ∂N/∂x = ∂N/∂ξ · J⁻¹.
  g.gradient = dn * j.inverse();
  g.volume = gp.weight * det;
  return g;
}

Eigen::Vector3d EdgeShapeFunctions(int nodes, double s) {
  if (nodes == 2) return Eigen::Vector3d(0.5 * (1.0 - s), 0.5 * (1.0 + s), 0.0);
  return Eigen::Vector3d(0.5 * s * (s - 1.0), 0.5 * s * (s + 1.0), 1.0 - s * s);
}

Eigen::Vector3d EdgeShapeDerivatives(int nodes, double s) {
  if (nodes == 2) return Eigen::Vector3d(-0.5, 0.5, 0.0);
  return Eigen::Vector3d(s - 0.5, s + 0.5, -2.0 * s);
}

std::span<const Eigen::Vector2d> EdgeGaussPoints() {
  static const std::array<Eigen::Vector2d, 3> points = {Eigen::Vector2d(-std::sqrt(0.6), 5.0 / 9.0),
                                                        Eigen::Vector2d(0.0, 8.0 / 9.0),
                                                        Eigen::Vector2d(std::sqrt(0.6), 5.0 / 9.0)};
  return points;
}

std::array<int, kMaxEdgeNodes> FaceNodes(ElementType type, int face) {
  const int start = face, end = (face + 1) % 4;
  return {start, end, type == ElementType::kQ4 ? -1 : 4 + face};
}

}  // namespace rvehub::fem
