// Isoparametric plane-strain elements: the 4-node bilinear quadrilateral Q4
// (2×2 Gauss points), the 8-node serendipity quadrilateral Q8 (3×3) and Q8R,
// the same 8 nodes with 2×2 points (the second-gradient element,
// second_gradient.h).
// Natural coordinates ξ = (ξ, η) ∈ [−1, 1]²; nodes counter-clockwise, the
// corners first (0: (−1,−1), 1: (1,−1), 2: (1,1), 3: (−1,1)), then Q8's
// midsides (4: edge 0–1, 5: 1–2, 6: 2–3, 7: 3–0).
#ifndef RVEHUB_FEM_CLIENT_CORE_ELEMENT_H_
#define RVEHUB_FEM_CLIENT_CORE_ELEMENT_H_

#include <Eigen/Dense>
#include <array>
#include <span>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace rvehub::fem {

enum class ElementType { kQ4, kQ8, kQ8R };

inline constexpr int kMaxElementNodes = 8;
inline constexpr int kMaxEdgeNodes = 3;

// Fixed capacity so that evaluating an element never allocates.
using ShapeVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxElementNodes, 1>;
// One row per node: ∂N_a/∂ξ_j (natural), ∂N_a/∂x_j (1/m) or x_a (m).
using ShapeGradient =
    Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::ColMajor, kMaxElementNodes, 2>;
using ElementCoordinates = ShapeGradient;

int NodeCount(ElementType type);                  // 4, 8, 8
int GaussPointCount(ElementType type);            // 4, 9, 4
int EdgeNodeCount(ElementType type);              // 2, 3, 3
absl::string_view ElementName(ElementType type);  // "Q4", "Q8", "Q8R"

struct GaussPoint {
  Eigen::Vector2d xi;  // natural coordinates
  double weight;       // [-]
};
// ξ varies fastest: Q4's and Q8R's points are (−,−), (+,−), (−,+), (+,+)
// at ±1/√3. Exact for polynomials of degree 3 (Q4, Q8R) and 5 (Q8) in each
// coordinate.
std::span<const GaussPoint> GaussPoints(ElementType type);

ShapeVector ShapeFunctions(ElementType type, const Eigen::Vector2d& xi);      // N_a, [-]
ShapeGradient ShapeDerivatives(ElementType type, const Eigen::Vector2d& xi);  // ∂N_a/∂ξ_j

// J_ij = ∂x_i/∂ξ_j = Σ_a x_ai ∂N_a/∂ξ_j (m).
Eigen::Matrix2d Jacobian(const ShapeGradient& dn_dxi, const ElementCoordinates& x);

// What an element contributes at one Gauss point in a configuration x.
struct PointGeometry {
  ShapeGradient gradient;  // ∂N_a/∂x_j, 1/m
  double volume = 0.0;     // weight·det J: m² per m of thickness
};

// The geometry at Gauss point `point` of an element (index `element`, for
// the message) at nodal positions x. InvalidArgument naming the element
// and the point when det J ≤ 0 there: "inverted" when negative,
// "degenerate" when zero to round-off (|det J| ≤ 1e-12 ‖J‖², its nodes
// collinear or coincident).
absl::StatusOr<PointGeometry> EvaluatePoint(ElementType type, const ElementCoordinates& x,
                                            int point, int element);

// Edge shape functions along s ∈ [−1, 1] for an edge of 2 or 3 nodes in the
// order start, end[, middle] (see Edge in mesh.h).
Eigen::Vector3d EdgeShapeFunctions(int nodes, double s);
Eigen::Vector3d EdgeShapeDerivatives(int nodes, double s);  // dN/ds
// 3-point Gauss rule on [−1, 1] as (s, weight): exact to degree 5, enough
// for the products N_a·dN_b/ds of either edge (degree ≤ 3).
std::span<const Eigen::Vector2d> EdgeGaussPoints();
// The element's local nodes of face f (0: nodes 0→1, 1: 1→2, 2: 2→3,
// 3: 3→0, then Q8's midside): start, end[, middle], the element on the left.
std::array<int, kMaxEdgeNodes> FaceNodes(ElementType type, int face);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_ELEMENT_H_
