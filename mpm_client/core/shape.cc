#include "mpm_client/core/shape.h"

#include <algorithm>
#include <cmath>

namespace rvehub::mpm {
namespace {

// 1-D weights of consecutive nodes first, first + 1, ... along one axis.
struct Axis1d {
  int first = 0;
  int count = 0;
  std::array<double, kMaxShapeNodesPerAxis> w;   // [-]
  std::array<double, kMaxShapeNodesPerAxis> dw;  // 1/m
};

// Hat function N(r) = max(0, 1 − |r|/h) of a node at distance r (m).
double Hat(double r, double h) { return std::max(0.0, 1.0 - std::abs(r) / h); }

// ∫_{−∞}^{r} N(s) ds, m: the antiderivative the GIMP weights average with.
double HatIntegral(double r, double h) {
  if (r <= -h) return 0.0;
  if (r <= 0.0) return (r + h) * (r + h) / (2.0 * h);
  if (r <= h) return h - (h - r) * (h - r) / (2.0 * h);
  return h;
}

// Linear hat weights of the cell holding x (x inside [x0, x0 + n h]).
void Linear1d(double x0, double h, int n, double x, Axis1d& out) {
  const double t = (x - x0) / h;
  const int k = std::clamp(static_cast<int>(std::floor(t)), 0, n - 1);
  const double xi = t - k;
  out.first = k;
  out.count = 2;
  out.w[0] = 1.0 - xi;
  out.w[1] = xi;
  out.dw[0] = -1.0 / h;
  out.dw[1] = 1.0 / h;
}

// Uniform GIMP: S_I = (1/|Ω_p|) ∫_Ω_p N_I and ∇S_I = (1/|Ω_p|) ∫_Ω_p ∇N_I over
// the point's domain Ω_p = [a, b] (eqs. 14–15). For lp ≤ h/2 and a domain
// inside the grid this is exactly the piecewise closed form of Bardenhagen &
// Kober (2004); written through the antiderivative it also covers clipped
// domains and lp up to h.
void Gimp1d(double x0, double h, int n, double x, double lp, Axis1d& out) {
  const double x_end = x0 + n * h;
  const double a = std::max(x - lp, x0);
  const double b = std::min(x + lp, x_end);
  const double inv_length = 1.0 / (b - a);
  const int lo = std::clamp(static_cast<int>(std::floor((a - x0) / h)), 0, n);
  const int hi =
      std::min({static_cast<int>(std::ceil((b - x0) / h)), n, lo + kMaxShapeNodesPerAxis - 1});
  out.first = lo;
  out.count = hi - lo + 1;
  for (int k = 0; k < out.count; ++k) {
    const double xi = x0 + (lo + k) * h;
    out.w[k] = (HatIntegral(b - xi, h) - HatIntegral(a - xi, h)) * inv_length;
    out.dw[k] = (Hat(b - xi, h) - Hat(a - xi, h)) * inv_length;
  }
}

}  // namespace

double HatShare(double a, double b, double x, double h, double lower, double upper) {
  // ∫_{-1}^{s} (1 − |u|) du for s ∈ [−1, 1], in cells.
  auto up_to = [](double s) {
    s = std::clamp(s, -1.0, 1.0);
    return s <= 0.0 ? 0.5 * (s + 1.0) * (s + 1.0) : 1.0 - 0.5 * (1.0 - s) * (1.0 - s);
  };
  a = std::max(a, lower);
  b = std::min(b, upper);
  if (!(b > a)) return 0.0;
  return up_to((b - x) / h) - up_to((a - x) / h);
}

bool InsideGrid(const GridSpec& grid, const Eigen::Vector2d& x) {
  const double h = grid.cell_size;
  // Written so that NaN coordinates count as outside.
  return x.x() >= grid.origin.x() && x.x() <= grid.origin.x() + grid.nx * h &&
         x.y() >= grid.origin.y() && x.y() <= grid.origin.y() + grid.ny * h;
}

bool EvaluateShape(const GridSpec& grid, ShapeKind kind, const Eigen::Vector2d& x,
                   const Eigen::Vector2d& half_size, ShapeValues& out) {
  if (!InsideGrid(grid, x)) return false;
  const double h = grid.cell_size;
  const int n[2] = {grid.nx, grid.ny};
  Axis1d axis[2];
  for (int d = 0; d < 2; ++d) {
    // lp = 0 is the linear limit of GIMP; lp beyond one cell is capped.
    const double lp = std::min(half_size[d], h);
    if (kind == ShapeKind::kGimp && lp > 0.0) {
      Gimp1d(grid.origin[d], h, n[d], x[d], lp, axis[d]);
    } else {
      Linear1d(grid.origin[d], h, n[d], x[d], axis[d]);
    }
  }
  // Tensor product: S = Sx·Sy, ∇S = (Sx'·Sy, Sx·Sy').
  out.count = 0;
  for (int j = 0; j < axis[1].count; ++j) {
    for (int i = 0; i < axis[0].count; ++i) {
      const int k = out.count++;
      out.node[k] = (axis[0].first + i) + (grid.nx + 1) * (axis[1].first + j);
      out.weight[k] = axis[0].w[i] * axis[1].w[j];
      out.gradient[k] = Eigen::Vector2d(axis[0].dw[i] * axis[1].w[j], axis[0].w[i] * axis[1].dw[j]);
    }
  }
  return true;
}

}  // namespace rvehub::mpm
