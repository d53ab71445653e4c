// Grid shape functions of the MPM background grid: the nodes that influence a
// material point, with weights S_Ip and gradients ∇S_Ip (paper eqs. 14–15).
// Nodes are numbered i + (nx + 1)·j, i along x, j along y.
#ifndef RVEHUB_MPM_CLIENT_CORE_SHAPE_H_
#define RVEHUB_MPM_CLIENT_CORE_SHAPE_H_

#include <Eigen/Dense>
#include <array>
#include <cstdint>

#include "mpm_client/core/model.h"

namespace rvehub::mpm {

// Up to 4 nodes per axis: a GIMP domain spans at most two cells because the
// half-size is capped at one cell (see EvaluateShape).
inline constexpr int kMaxShapeNodesPerAxis = 4;
inline constexpr int kMaxShapeNodes = kMaxShapeNodesPerAxis * kMaxShapeNodesPerAxis;

// Fixed capacity so that evaluating a point never allocates.
struct ShapeValues {
  int count = 0;
  std::array<std::int32_t, kMaxShapeNodes> node;
  std::array<double, kMaxShapeNodes> weight;             // S_Ip, [-]
  std::array<Eigen::Vector2d, kMaxShapeNodes> gradient;  // ∇S_Ip, 1/m
};

// Current GIMP half-sizes: lp0 stretched like the material along each axis,
// lp_i = lp0_i·|F e_i|, m.
inline Eigen::Vector2d CurrentHalfSize(const Eigen::Matrix2d& f, const Eigen::Vector2d& lp0) {
  return Eigen::Vector2d(lp0.x() * f.col(0).norm(), lp0.y() * f.col(1).norm());
}

inline int NodeCount(const GridSpec& grid) { return (grid.nx + 1) * (grid.ny + 1); }

inline Eigen::Vector2d NodePosition(const GridSpec& grid, int node) {
  const int i = node % (grid.nx + 1), j = node / (grid.nx + 1);
  return grid.origin + grid.cell_size * Eigen::Vector2d(i, j);
}

// The integral of a node's bilinear hat along one axis over [a, b] ∩
// [lower, upper], for the node at x on cells of size h (m), in units of h,
// [-]: 1 for its whole support, ½ from the node to one side. How much of a
// node's volume lies in a slab (a body, the soil side of a wall).
double HatShare(double a, double b, double x, double h, double lower, double upper);

// True when x lies in the closed grid rectangle.
bool InsideGrid(const GridSpec& grid, const Eigen::Vector2d& x);

// The nodes influencing a point at x (m) with half-size half_size (m, per
// axis; GIMP only). Linear: the bilinear hat functions of the point's cell
// (4 nodes). GIMP: the hat functions averaged over the point's domain
// [x − lp, x + lp] (uniform GIMP, Bardenhagen & Kober 2004); the domain is
// clipped to the grid so that the weights still sum to one at the border,
// and lp is capped at one cell (a point stretched further has failed to
// resolve the deformation anyway). Returns false, with out unspecified, when
// x lies outside the grid.
bool EvaluateShape(const GridSpec& grid, ShapeKind kind, const Eigen::Vector2d& x,
                   const Eigen::Vector2d& half_size, ShapeValues& out);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_SHAPE_H_
